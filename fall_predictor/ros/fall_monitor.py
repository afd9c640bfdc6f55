"""fall_monitor: the onboard fall monitor's nodes in one process, on one executor.

Runs :data:`MONITOR_NODES` (the feature node and the predictor node; with ``--estimator`` the
state estimator node first, for a robot that publishes its raw sensors instead of the
measurement) as separate ROS nodes, with their own names,
parameters, services and ``/diagnostics`` entries, but in one process spun by one
``SingleThreadedExecutor``. Inside the process each node hands its output message to the next
node's input callback directly (:class:`~fall_predictor.ros.in_process.Output`, intra-process
delivery as in rclcpp) and still publishes it for other processes (recorders, tools): a sample
goes from measurement to state in one executor wake-up, with no DDS round trip and no
(de)serialization between the nodes. The downstream nodes therefore do not subscribe to those
topics: in this process the predictor takes the features of its own feature node only.

    ros2 run fall_predictor fall_monitor [--estimator] --ros-args -r __ns:=/robot1 \\
        --params-file config/monitor.yaml

A Unitree G1 (its ``lowstate`` instead of ``joint_states`` and ``imu/data``; the estimator's
``input`` parameter, method §12)::

    ros2 run fall_predictor fall_monitor --estimator --ros-args -p input:=unitree_hg \\
        -p robot:=g1_12dof

Namespace and remappings given on the command line apply to every node of the process; do not
rename the nodes (``-r __node:=``), each keeps its own name. Exit code 1, with one FATAL line,
when a node cannot start (no model, a bad parameter): then none runs.
"""
from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from typing import Optional

from rclpy.node import Node

from fall_predictor.ros.runner import run_nodes
from fall_predictor.ros.feature_node import FeatureNode
from fall_predictor.ros.predictor_node import PredictorNode

NAME = 'fall_monitor'
#: The monitor's nodes, in data-flow order (the first node's output feeds the next).
MONITOR_NODES = (FeatureNode, PredictorNode)
#: Option (before ``--ros-args``) that adds the state estimator in front of them.
ESTIMATOR_OPTION = '--estimator'


def in_process_chain(node_classes: Sequence[type], **node_kwargs: object
                     ) -> list[Callable[[], Node]]:
    """Factories of ``node_classes`` (data-flow order) in which each node takes its input from
    the previous node's ``output`` in process (``upstream``); the first one subscribes.
    ``node_kwargs`` go to every node (``context``, ``parameter_overrides``)."""
    created: list[Node] = []

    def factory(node_class: type) -> Callable[[], Node]:
        def make() -> Node:
            if created:
                node = node_class(upstream=created[-1].output, **node_kwargs)
            else:
                node = node_class(**node_kwargs)
            created.append(node)
            return node
        return make
    return [factory(node_class) for node_class in node_classes]


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.fall_monitor [--estimator] --ros-args ...``."""
    argv = list(sys.argv if args is None else args)
    with_estimator = ESTIMATOR_OPTION in argv
    if with_estimator:
        argv.remove(ESTIMATOR_OPTION)
        # Imported only when asked for: it brings Pinocchio.
        from fall_predictor.ros.state_estimator_node import StateEstimatorNode
        return run_nodes(in_process_chain((StateEstimatorNode, *MONITOR_NODES)), NAME, argv)
    return run_nodes(in_process_chain(MONITOR_NODES), NAME, argv)


if __name__ == '__main__':
    raise SystemExit(main())
