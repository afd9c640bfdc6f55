"""The message contract of the live path: every topic's name, type, QoS, rate and frame
(:mod:`~fall_predictor.contract.topics`), and the conversions between the monitor's records and the
messages that carry them (:mod:`~fall_predictor.contract.messages`: the package's own typed messages
and the robot's standard sensor messages; :mod:`~fall_predictor.contract.wire`: the array layouts of
bags recorded before the typed messages). The nodes, the recorder and the bag tools all convert
through here, so a message means the same thing live and offline.

May import: fall_predictor.monitor, numpy. No ROS imports: the conversions work on rclpy messages
and rosbags messages alike (they share field names), with the message classes passed in.
"""
