"""fall_monitor: the onboard fall monitor's nodes in one process, on one executor.

Runs :data:`MONITOR_NODES` (the feature node and the predictor node; with ``--estimator`` the
state estimator node first, for a robot that publishes its raw sensors instead of the
measurement) as separate ROS nodes, with their own names,
parameters, services and ``/diagnostics`` entries, but in one process spun by one
``SingleThreadedExecutor``: a sample goes from measurement to state without crossing a process
boundary, which is cheaper than two processes on a small onboard computer.

    ros2 run fall_predictor fall_monitor [--estimator] --ros-args -r __ns:=/robot1 \\
        --params-file config/monitor.yaml

Namespace and remappings given on the command line apply to every node of the process; do not
rename the nodes (``-r __node:=``), each keeps its own name. Exit code 1, with one FATAL line,
when a node cannot start (no model, a bad parameter): then none runs.
"""
from __future__ import annotations

import sys
from typing import Optional

from fall_predictor.ros.common import run_nodes
from fall_predictor.ros.feature_node import FeatureNode
from fall_predictor.ros.predictor_node import PredictorNode

NAME = 'fall_monitor'
#: The monitor's nodes, in data-flow order (the first node's output feeds the next).
MONITOR_NODES = (FeatureNode, PredictorNode)
#: Option (before ``--ros-args``) that adds the state estimator in front of them.
ESTIMATOR_OPTION = '--estimator'


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.fall_monitor [--estimator] --ros-args ...``."""
    argv = list(sys.argv if args is None else args)
    with_estimator = ESTIMATOR_OPTION in argv
    if with_estimator:
        argv.remove(ESTIMATOR_OPTION)
        # Imported only when asked for: it brings Pinocchio.
        from fall_predictor.ros.state_estimator_node import StateEstimatorNode
        return run_nodes((StateEstimatorNode, *MONITOR_NODES), NAME, argv)
    return run_nodes(MONITOR_NODES, NAME, argv)


if __name__ == '__main__':
    raise SystemExit(main())
