"""What runs onboard, next to the balance controller: the data records, support-polygon
geometry, the 16 contact modes, the CoP-frame features, per-contact-mode decision lists or
boosted trees, the online predictor with its tau_his window and CoM guard, and the model file
that carries a trained predictor to the robot.

May import: numpy and the standard library only (Pinocchio for the state estimator). Nothing
here knows about PyBullet, ROS, scikit-learn or files of recorded data, so the same code runs in
the ROS nodes and in every offline tool.
"""
