"""The five nodes of the package as separate processes over real DDS, for
``test_nodes_pipeline.py``: starting them on a private domain, following a run through the
tests' :class:`~fall_predictor.ros.observer.Observer`, and what a run received."""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from rcl_interfaces.msg import SetParametersResult
from test_nodes_support import write_momentum_model

from fall_predictor.ros.bringup import (UNPACED_PREDICTOR_PARAMS, NodeProcess, default_params_file,
                                        ros_environment, start_node)
from fall_predictor.ros.observer import ModeChange, Observer, ObservedState, ReceivedSample

#: Wall-clock limit of each run [s] (a run normally takes 2 to 4 ms per simulated ms).
RUN_TIMEOUT_S = 120.0
#: Wall-clock limit for the nodes to start and connect [s].
CONNECT_TIMEOUT_S = 60.0


class SystemNotRunning(RuntimeError):
    """The system under test could not be started or driven (not a failed check)."""


@dataclass
class Run:
    """What the observer received during one run."""

    samples: list[ReceivedSample]
    states: list[ObservedState]
    modes: list[ModeChange]
    #: /diagnostics counters of the feature and predictor nodes right after the run.
    counters: dict[str, dict[str, str]]

    @property
    def t_fallen(self) -> float | None:
        return next((t for t, fallen in self.samples if fallen), None)


@dataclass
class System:
    """The running nodes and the tests' observer."""

    observer: Observer
    nodes: dict[str, NodeProcess]
    tmp: Path


@dataclass
class Runs:
    """What the two runs produced, recorded for the tests to check."""

    no_push: Run
    strong_push: Run
    #: The predictor's answer to the run-time change of ``tau_his_s``.
    tau_his_change: list[SetParametersResult]
    t_tau_his_set: float                     #: sample time when the change was acknowledged
    #: The malformed joint commands had both their subscribers (simulator, recorder).
    bad_commands_matched: bool


def start_nodes(tmp: Path, domain: int, nodes: dict[str, NodeProcess]) -> None:
    """Start the five nodes into ``nodes`` (filled as they start, so all can be stopped)."""
    env = ros_environment(domain)
    params = default_params_file()
    model = write_momentum_model(tmp / 'model.json')
    overrides = {
        # The recorder first, so that it is matched before anything is published.
        'recorder_node': {'bag_path': str(tmp / 'bags')},
        # No startup STALE states before the recorder has surely matched the predictor; the
        # simulator runs unpaced, so the sample-age check is off as in an unpaced bring-up
        # (on a busy machine the predictor lags /clock in simulated time only).
        'predictor_node': {'model_path': str(model), 'stale_timeout_s': '5.0',
                           **UNPACED_PREDICTOR_PARAMS},
        'feature_node': {},
        'controller_node': {},
        'simulator_node': {'autostart': 'false', 'real_time_factor': '0.0'},
    }
    for name, values in overrides.items():
        nodes[name] = start_node(name, params, values, env, tmp)
        if name == 'recorder_node':
            time.sleep(1.0)


def dead_nodes(nodes: dict[str, NodeProcess]) -> str:
    """Each node process that has exited, with the end of its log ('' while all run)."""
    return '\n'.join(f'{node.name} died:\n{node.log_tail()}' for node in nodes.values()
                     if node.process.poll() is not None)


def check_alive(nodes: dict[str, NodeProcess]) -> None:
    dead = dead_nodes(nodes)
    if dead:
        raise SystemNotRunning(dead)


def follow(observer: Observer, nodes: dict[str, NodeProcess], until: float) -> None:
    """Spin until sample time ``until`` [s] or fallen."""
    def reached() -> bool:
        return observer.t_last >= until or bool(observer.samples and observer.samples[-1].fallen)

    if not observer.spin_until(reached, RUN_TIMEOUT_S, lambda: check_alive(nodes)):
        raise SystemNotRunning(f'run stuck at t = {observer.t_last} s (waiting for {until} s)')


def run(observer: Observer, nodes: dict[str, NodeProcess], until: float) -> Run:
    """Follow the current run until sample time ``until`` [s] or fallen, then pause; what was
    received, and the monitor's counters at that point."""
    follow(observer, nodes, until)
    observer.pause_world()
    observer.spin_for(0.5, lambda: check_alive(nodes))          # states still in flight
    end = observer.t_last
    counters = {name: dict(observer.fresh_diagnostics(name).values)
                for name in ('feature_node', 'predictor_node')}
    return Run([s for s in observer.samples if s.t <= end],
               [s for s in observer.states if s.t <= end], list(observer.modes), counters)
