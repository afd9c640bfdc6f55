"""simulated_robot: the simulator and the controller nodes in one process, on one executor.

The simulated stand-in for a robot's own process: :class:`~fall_predictor.ros.simulator_node.
SimulatorNode` and :class:`~fall_predictor.ros.controller_node.ControllerNode` stay separate
ROS nodes (own names, parameters, services, ``/diagnostics``), but the lock-step loop between
them is closed in process (:mod:`fall_predictor.ros.in_process`): the controller takes each
measurement from the simulator directly and its joint command goes straight back, while both
topics are still published for the monitor, recorders and tools. The world steps up to five
times per executor wake-up; the fall trigger, push requests, timers and services are served in
between, so the controller sees the trigger at most 5 ms of simulation time later than as a
separate process. With ``publish_sensors`` the controller takes the simulator's exact state
(``fall_predictor/ground_truth``) in process the same way, as C_bal does in data generation. A
learned policy (``controller``) reads the robot's sensor topics instead, over DDS within the
process: the simulator publishes each sample's sensors before it awaits the answer, the policy
answers that sample, and its command comes back in process; the run equals the offline loop's
(``sim/trajectory.py``) with the same sensor noise.

    ros2 run fall_predictor simulated_robot --ros-args --params-file config/fall_predictor.yaml

Exit code 1, with one FATAL line, when a node cannot start.
"""
from __future__ import annotations

from typing import Optional

from rclpy.node import Node
from rclpy.parameter import Parameter

from fall_predictor.contract.topics import GROUND_TRUTH
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
        # The simulator's exact state, on measurement or (with sensors) on ground_truth.
        truth = sim.output.topic_name == sim.resolve_topic_name(GROUND_TRUTH.ros_name)
        others = {k: v for k, v in node_kwargs.items() if k != 'parameter_overrides'}
        overrides = [*node_kwargs.get('parameter_overrides', []), Parameter('ground_truth', value=truth)]
        node = ControllerNode(upstream=sim.output, parameter_overrides=overrides, **others)
        sim.connect_controller(node.output)
        return node
    return [simulator, controller]


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.simulated_robot --ros-args ...``."""
    return run_nodes(robot_nodes(), NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
