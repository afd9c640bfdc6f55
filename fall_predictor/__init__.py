"""fall_predictor: learned humanoid fall prediction.

Sub-packages, from the robot outwards: ``monitor`` (what runs onboard; numpy only), ``profiles``
(one file per robot: every robot-specific fact), ``robot`` (the simulated humanoid and its
controllers), ``sim`` (the PyBullet testbed), ``data`` (topic
contract, bags, datasets), ``learning`` (training and evaluation) and ``ros`` (the ROS 2 nodes,
the only place that imports rclpy). ``cli`` is the ``fall-predictor`` front end.
"""

__version__ = '0.1.0'
