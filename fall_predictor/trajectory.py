"""Run one push trajectory with C_bal throughout and return its time series and outcome."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from fall_predictor.controllers import BalanceController, ControllerSwitch, GaitConfig, ReflexConfig
from fall_predictor.records import Measurement, PushSpec
from fall_predictor.simulator import Simulator, SimulatorConfig


@dataclass
class TrajectoryResult:
    """A simulated trajectory: one measurement per 1 ms step, joint states, and its outcome."""

    push: Optional[PushSpec]
    measurements: list[Measurement]
    joint_positions: np.ndarray          #: (N, 26) [rad]
    joint_velocities: np.ndarray         #: (N, 26) [rad/s]
    fallen: bool
    t_fallen: Optional[float]
    t_reflex: Optional[float]
    t_switch: Optional[float] = None     #: when C_fall took over, if it did
    extras: dict = field(default_factory=dict)

    @property
    def t(self) -> np.ndarray:
        return np.array([m.t for m in self.measurements])

    @property
    def com(self) -> np.ndarray:
        return np.array([m.com for m in self.measurements])

    @property
    def t_push(self) -> Optional[float]:
        return None if self.push is None else self.push.t_push


def run_trajectory(push: Optional[PushSpec], duration_s: float,
                   gait: GaitConfig = GaitConfig(), reflex: ReflexConfig = ReflexConfig(),
                   sim_config: SimulatorConfig = SimulatorConfig(),
                   stop_when_fallen: bool = True, settle_after_push_s: Optional[float] = None,
                   fall_trigger: Optional[Callable[[Measurement], bool]] = None,
                   simulator: Optional[Simulator] = None) -> TrajectoryResult:
    """Simulate from the standing posture for up to ``duration_s`` seconds.

    Stops early when fallen (if ``stop_when_fallen``) or ``settle_after_push_s`` after the push
    ends. ``fall_trigger`` (a predictor) is asked every step; when it says falling, C_bal hands
    over to C_fall for the rest of the run.
    """
    own = simulator is None
    sim = simulator or Simulator(sim_config)
    try:
        balance = BalanceController(gait, reflex, sim.config.dt_s, walk_duration_s=duration_s + 5.0)
        q0, torso0 = balance.initial_posture()
        m = sim.reset(q0, torso0)
        switch = ControllerSwitch(balance)
        if push is not None:
            sim.schedule_push(push)
        t_end = duration_s
        if push is not None and settle_after_push_s is not None:
            t_end = min(t_end, push.t_force_end + settle_after_push_s)
        ms: list[Measurement] = [m]
        qs, dqs = [], []
        q, dq, _ = sim.joint_states()
        qs.append(q)
        dqs.append(dq)
        t_fallen = None
        while sim.t < t_end - 1e-9:
            if fall_trigger is not None and switch.mode == 'balance' and fall_trigger(m):
                switch.trigger_fall(m.t)
            sim.set_joint_targets(switch.update(m))
            m = sim.step()
            ms.append(m)
            q, dq, _ = sim.joint_states()
            qs.append(q)
            dqs.append(dq)
            if t_fallen is None and m.fallen:
                t_fallen = m.t
                if stop_when_fallen:
                    break
        event = balance.reflex_event
        return TrajectoryResult(push=push, measurements=ms, joint_positions=np.array(qs),
                                joint_velocities=np.array(dqs), fallen=t_fallen is not None,
                                t_fallen=t_fallen, t_reflex=None if event is None else event.t,
                                t_switch=switch.t_switch)
    finally:
        if own:
            sim.close()
