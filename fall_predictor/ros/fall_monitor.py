"""fall_monitor: the onboard fall monitor's nodes in one process, on one executor.

Runs :data:`MONITOR_NODES` (the feature node and the predictor node; the state estimator joins
them when the robot publishes raw sensors) as separate ROS nodes, with their own names,
parameters, services and ``/diagnostics`` entries, but in one process spun by one
``SingleThreadedExecutor``: a sample goes from measurement to state without crossing a process
boundary, which is cheaper than two processes on a small onboard computer.

    ros2 run fall_predictor fall_monitor --ros-args -r __ns:=/robot1 \\
        --params-file config/monitor.yaml

Namespace and remappings given on the command line apply to every node of the process; do not
rename the nodes (``-r __node:=``), each keeps its own name. Exit code 1, with one FATAL line,
when a node cannot start (no model, a bad parameter): then none runs.
"""
from __future__ import annotations

from typing import Optional

from fall_predictor.ros.common import run_nodes
from fall_predictor.ros.feature_node import FeatureNode
from fall_predictor.ros.predictor_node import PredictorNode

NAME = 'fall_monitor'
#: The monitor's nodes, in data-flow order (the first node's output feeds the next).
MONITOR_NODES = (FeatureNode, PredictorNode)


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.fall_monitor --ros-args ...``."""
    return run_nodes(MONITOR_NODES, NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
