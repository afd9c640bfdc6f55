"""The ROS 2 side, and the only sub-package that imports rclpy: one module per node
(``simulator_node``, ``controller_node``, ``feature_node``, ``predictor_node``,
``recorder_node``), message conversions and QoS, what the nodes share (:mod:`.common`), and the
bring-up of the whole system as separate processes with its observer. Each node is a thin
wrapper around the ROS-free code it runs. Run one with ``python -m fall_predictor.ros.<node>
--ros-args --params-file config/fall_predictor.yaml``.

May import: everything in fall_predictor.
"""
