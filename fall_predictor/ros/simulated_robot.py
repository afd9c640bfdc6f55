"""simulated_robot: the simulator and the controller nodes in one process, on one executor.

The simulated stand-in for a robot's own process: :class:`~fall_predictor.ros.simulator_node.
SimulatorNode` and :class:`~fall_predictor.ros.controller_node.ControllerNode` stay separate
ROS nodes (own names, parameters, services, ``/diagnostics``), but the lock-step loop between
them is closed in process (:mod:`fall_predictor.ros.in_process`): the controller takes each
measurement from the simulator directly and its joint command goes straight back, while both
topics are still published for the monitor, recorders and tools. The world steps up to five
times per executor wake-up; the fall trigger, push requests, timers and services are served in
between, so the controller sees the trigger at most 5 ms of simulation time later than as a
separate process. With ``publish_sensors`` the controller reads the state estimator's
measurement over DDS as usual (only the commands stay in process).

    ros2 run fall_predictor simulated_robot --ros-args --params-file config/fall_predictor.yaml

Exit code 1, with one FATAL line, when a node cannot start.
"""
from __future__ import annotations

from typing import Optional

from rclpy.node import Node

from fall_predictor.contract.topics import MEASUREMENT
from fall_predictor.ros.runner import run_nodes
from fall_predictor.ros.controller_node import ControllerNode
from fall_predictor.ros.simulator_node import SimulatorNode

NAME = 'simulated_robot'


def robot_nodes(simulator_class: type = SimulatorNode, **node_kwargs: object) -> list:
    """Factories of the simulator (``simulator_class``, a :class:`SimulatorNode`) and the
    controller, connected in process, in this order. ``node_kwargs`` go to both nodes
    (``context``, ``parameter_overrides``)."""
    created: list[Node] = []

    def simulator() -> Node:
        created.append(simulator_class(in_process_controller=True, **node_kwargs))
        return created[0]

    def controller() -> Node:
        sim = created[0]
        # The simulator's own measurement (no sensors): taken in process; else over DDS.
        in_process = sim.output.topic_name == sim.resolve_topic_name(MEASUREMENT.ros_name)
        node = ControllerNode(upstream=sim.output if in_process else None, **node_kwargs)
        sim.connect_controller(node.output)
        return node
    return [simulator, controller]


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.simulated_robot --ros-args ...``."""
    return run_nodes(robot_nodes(), NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
