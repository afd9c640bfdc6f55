"""Run one push trajectory and return its time series and outcome, for any robot, controller and
simulator.

A run is a world of the simulator seam (:mod:`fall_predictor.sim.world`: PyBullet or MuJoCo) and a
controller of the controller seam (:mod:`fall_predictor.robot.control`: C_bal, or a team's
learned policy), switched to C_fall for good when a fall trigger says so. Every physics step the
world measures the exact state (the labels, and what C_bal reads); when the controller observes
the sensors (a learned policy) or the run records them, the world's exact sensor quantities go
through the sensor model (:class:`~fall_predictor.sim.sensors.SensorSuite`, seeded) as the run
goes, so that what a policy saw is what the bags record. The controller decides every one of its
periods and its command is held in between.

With C_bal's fixed gait every trajectory walks the same walk until its push, so the walk before
the push need not be simulated again for each one: a :class:`WalkPrefix` simulates the unpushed
walk once, keeps its samples and snapshots, and pushed trajectories start from the last snapshot
before their push. A trajectory from a prefix depends only on its push, not on what the prefix's
world ran before (:meth:`~fall_predictor.sim.world.World.restore`); for a robot with one collision shape per link it
equals one run from a fresh world bit for bit; for one whose links have several (the G1's sole
spheres, whose contacts PyBullet restores only approximately) it departs from that run from the
first step after the snapshot, as two runs whose contact forces differ slightly do
(``test_simulator.py`` and ``test_g1.py`` check each).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from fall_predictor.profiles.profile import DEFAULT_ROBOT, load_profile
from fall_predictor.robot.control import (Controller, ControllerSwitch, Observation, OBSERVES_SENSORS,
                                          make_controller)
from fall_predictor.monitor.records import Measurement, PushSpec
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.robot.stabilizer import StabilizerConfig
from fall_predictor.sim.pybullet_world import PybulletConfig
from fall_predictor.sim.sensors import SensorParams, SensorSuite
from fall_predictor.sim.world import World, make_world

#: The simulated robot, as datasets record it.
ROBOT_NAME = 'asimo_like'
ROBOT_TOTAL_MASS_KG = rm.TOTAL_MASS_KG
ROBOT_JOINT_NAMES = rm.JOINT_NAMES
#: How the simulated robot is driven (recorded in every dataset's manifest).
#: :func:`run_trajectory`: how long a run goes on at a time while ``go_on_while`` says so [s].
EXTENSION_STEP_S = 0.5
#: C_bal's walk is planned this much longer than the run it walks [s]: it never ends in a run.
WALK_MARGIN_S = 5.0
ROBOT_CONTROL = {'actuation': PybulletConfig().actuation, 'stabilizer': StabilizerConfig().enabled}


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
    #: Exact sensor quantities per step (sim/sensors.py), when recorded; else empty.
    sensor_truths: list = field(default_factory=list)
    #: The sensor model's readings per step, when the run made them (a controller that observes
    #: the sensors saw these); else empty.
    sensor_readings: list = field(default_factory=list)

    @property
    def t(self) -> np.ndarray:
        return np.array([m.t for m in self.measurements])

    @property
    def com(self) -> np.ndarray:
        return np.array([m.com for m in self.measurements])

    @property
    def t_push(self) -> Optional[float]:
        return None if self.push is None else self.push.t_push


@dataclass
class _Run:
    """The mutable state of a run in progress."""

    switch: ControllerSwitch
    measurement: Measurement
    measurements: list[Measurement]
    joint_positions: list[np.ndarray]
    joint_velocities: list[np.ndarray]
    t_fallen: Optional[float] = None
    sensor_truths: Optional[list] = None     #: None: not recorded
    #: The live sensor model and its readings (None: the run makes no readings).
    sensors: Optional[SensorSuite] = None
    sensor_readings: Optional[list] = None


def _new_run(world: World, walk_duration_s: float, record_sensors: bool = False,
             controller: Optional[Controller] = None, sensors: Optional[SensorSuite] = None) -> _Run:
    """A run from the controller's starting posture in a fresh world: ``controller``, or the
    robot's default controller (C_bal with its profile's settings, or its learned policy) walking
    for ``walk_duration_s``; ``sensors``: the live sensor model (made when the controller observes
    the sensors and none is given)."""
    if controller is None:
        controller = make_controller(world.profile, dt_s=world.dt_s, walk_duration_s=walk_duration_s)
    switch = ControllerSwitch(controller)
    if sensors is None and switch.walking.observes == OBSERVES_SENSORS:
        sensors = SensorSuite(SensorParams(), 0, world.dt_s, world.profile)
    m = world.start(switch.walking.initial_posture())
    q, dq, _ = world.joint_states()
    run = _Run(switch, m, [m], [q], [dq], sensors=sensors)
    if record_sensors or sensors is not None:
        truth = world.sensor_truth()
        run.sensor_truths = [truth] if record_sensors else None
        if sensors is not None:
            run.sensor_readings = [sensors.read(truth)]
    return run


def _advance(sim: World, run: _Run, t_end: float, stop_when_fallen: bool,
             fall_trigger: Optional[Callable[[Measurement], bool]] = None,
             on_step: Optional[Callable] = None) -> None:
    """Step until ``t_end``, or until the first fallen state if ``stop_when_fallen``;
    ``on_step(world, measurement)`` after each step (a renderer, a probe)."""
    m = run.measurement
    switch = run.switch
    every = max(1, int(round(switch.walking.period_s / sim.dt_s)))
    record = run.sensor_truths is not None
    suite, readings = run.sensors, run.sensor_readings
    while sim.t < t_end - 1e-9:
        if fall_trigger is not None and switch.mode == 'balance' and fall_trigger(m):
            switch.trigger_fall(m.t)
        if sim.tick % every == 0:
            sensors = readings[-1] if readings else None
            sim.apply(switch.command(Observation(m.t, m, sensors)))
        m = sim.step()
        if on_step is not None:
            on_step(sim, m)
        run.measurements.append(m)
        q, dq, _ = sim.joint_states()
        run.joint_positions.append(q)
        run.joint_velocities.append(dq)
        if record or suite is not None:
            truth = sim.sensor_truth()
            if record:
                run.sensor_truths.append(truth)
            if suite is not None:
                readings.append(suite.read(truth))
        if run.t_fallen is None and (m.com[2] < sim.profile.fallen_com_height_m or m.non_foot_contact):
            run.t_fallen = m.t
            if stop_when_fallen:
                break
    run.measurement = m


class WalkPrefix:
    """The unpushed walk of one world, simulated once, with snapshots to start from.

    Owns its world: do not start it again while the prefix is in use. ``controller``: the walking
    controller (default: the robot's, walking for ``walk_duration_s``); a deterministic one (C_bal:
    its fixed gait), whose copies at each snapshot continue as it would have.
    """

    def __init__(self, sim: World, until_s: float, walk_duration_s: float,
                 controller: Optional[Controller] = None, snapshot_every_s: float = 0.1,
                 record_sensors: bool = False):
        self.sim = sim
        self.walk_duration_s = walk_duration_s
        run = _new_run(sim, walk_duration_s, record_sensors, controller)
        self.record_sensors = record_sensors
        self._snapshots: list[tuple[float, int, object, _Run]] = []
        every = max(1, int(round(snapshot_every_s / sim.dt_s)))
        while sim.t < until_s - 1e-9:
            if sim.tick % every == 0:
                self._snapshot(run)
            _advance(sim, run, sim.t + sim.dt_s, stop_when_fallen=True)
            if run.t_fallen is not None:
                raise RuntimeError(f'the unpushed walk fell at {run.t_fallen:.3f} s')
        self._snapshot(run)
        self.run = run
        self.until_s = until_s

    def _snapshot(self, run: _Run) -> None:
        state = self.sim.save_state()
        frozen = _Run(copy.deepcopy(run.switch), run.measurement, [], [], [])
        self._snapshots.append((self.sim.t, self.sim.tick, state, frozen))

    def start_at(self, t: float) -> _Run:
        """Restore the latest snapshot at or before ``t``; the run holds all samples up to it."""
        if t > self.until_s + 1e-9:
            raise ValueError(f'the prefix covers {self.until_s} s, not {t} s')
        t_snap, tick, state, frozen = max((s for s in self._snapshots if s[0] <= t + 1e-9), key=lambda s: s[0])
        self.sim.restore(state, tick, frozen.measurement)
        n = tick + 1
        truths = None if self.run.sensor_truths is None else self.run.sensor_truths[:n]
        return _Run(copy.deepcopy(frozen.switch), frozen.measurement, self.run.measurements[:n],
                    self.run.joint_positions[:n], self.run.joint_velocities[:n], sensor_truths=truths)


def run_trajectory(push: Optional[PushSpec], duration_s: float, *,
                   world: Optional[World] = None,
                   controller: Optional[Controller] = None,
                   prefix: Optional[WalkPrefix] = None,
                   stop_when_fallen: bool = True,
                   fall_trigger: Optional[Callable[[Measurement], bool]] = None,
                   record_sensors: bool = False,
                   sensors: Optional[SensorSuite] = None,
                   go_on_while: Optional[Callable[[list[Measurement]], bool]] = None,
                   max_extension_s: float = 0.0,
                   on_step: Optional[Callable] = None,
                   disturbance=None, randomization=None) -> TrajectoryResult:
    """Simulate from the controller's starting posture for up to ``duration_s`` seconds.

    ``world``: the world to run in (any world of sim/world.py; default: a fresh one of the
    package's default robot, closed at the end); ``controller``: the walking controller (default:
    the robot's, robot/control.make_controller); ``sensors``: the sensor model run live (its
    readings are in the result; a controller that observes the sensors gets one with the default
    parameters when none is given); ``on_step(world, measurement)``: called after each step.

    Stops early when fallen (if ``stop_when_fallen``). ``fall_trigger`` (a predictor) is asked
    every step; when it says falling, the walking controller hands over to C_fall for the rest
    of the run. With a ``prefix`` the walk before the push is taken from it (same result, less
    simulation). ``record_sensors`` keeps the exact sensor quantities of every step (the prefix
    must have been made with it too). ``go_on_while``: asked with the samples so far when a run
    that has not fallen reaches ``duration_s``; while it says so the run goes on, in steps of
    :data:`EXTENSION_STEP_S`, for up to ``max_extension_s`` more seconds (a robot still moving
    when the horizon ends: its outcome is not known yet). ``disturbance``: a disturbance beyond
    pushes (sim/disturbances.Disturbance): its terrain laid before the start, its fault scheduled,
    a long walk's command schedule followed, its onset measured (``extras['t_onset']``,
    sim/disturbance_runs.OnsetProbe); the world is flat and sound again afterwards.
    ``randomization``: the run's randomised world (sim/randomization.WorldRandomization; its
    sensors' part is the ``sensors`` given), nominal again afterwards.
    """
    if randomization is not None and prefix is not None:
        raise ValueError('a randomised run starts its own world: no shared walk prefix')
    if prefix is not None and disturbance is None and push is not None and push.t_push <= prefix.until_s:
        sim = prefix.sim
        run = prefix.start_at(push.t_push)
        own = False
    else:
        own = world is None and prefix is None
        sim = prefix.sim if prefix is not None else (world or make_world(load_profile(DEFAULT_ROBOT)))
        probe = None
        if randomization is not None:
            if not callable(getattr(sim, 'set_randomization', None)):
                raise ValueError(f'the {type(sim).__name__} world cannot be randomised: it lacks '
                                 'set_randomization (sim/world.py World)')
            sim.set_randomization(randomization)
        if disturbance is not None:
            probe, controller, on_step = _disturbed(sim, disturbance, controller, on_step)
        run = _new_run(sim, duration_s + max_extension_s + WALK_MARGIN_S, record_sensors, controller,
                       sensors)
    try:
        if push is not None:
            sim.schedule_push(push)
        if disturbance is not None and disturbance.fault is not None:
            sim.schedule_fault(disturbance.fault)
        _advance(sim, run, duration_s, stop_when_fallen, fall_trigger, on_step)
        end_s = duration_s + max_extension_s
        while (go_on_while is not None and run.t_fallen is None and sim.t < end_s - 1e-9
               and go_on_while(run.measurements)):
            _advance(sim, run, min(sim.t + EXTENSION_STEP_S, end_s), stop_when_fallen, fall_trigger,
                     on_step)
        t_fallen = run.t_fallen
        event = run.switch.walking.reflex_event
        return TrajectoryResult(push=push, measurements=run.measurements,
                                joint_positions=np.array(run.joint_positions),
                                joint_velocities=np.array(run.joint_velocities),
                                fallen=t_fallen is not None, t_fallen=t_fallen,
                                t_reflex=None if event is None else event.t,
                                t_switch=run.switch.t_switch,
                                sensor_truths=run.sensor_truths or [],
                                sensor_readings=run.sensor_readings or [],
                                extras={} if disturbance is None else {'t_onset': probe.t_onset})
    finally:
        if disturbance is not None and disturbance.terrain:
            sim.set_terrain(())
        if randomization is not None:
            sim.set_randomization(None)
        if own:
            sim.close()


def _disturbed(sim: World, disturbance, controller: Optional[Controller], on_step):
    """A disturbed run's onset probe, controller and step callback; its terrain laid."""
    from fall_predictor.sim.disturbance_runs import OnsetProbe, ScheduledCommand
    from fall_predictor.sim.world import require_disturbances
    require_disturbances(sim, disturbance.cause)
    sim.set_terrain(disturbance.terrain)
    probe = OnsetProbe(disturbance)
    if disturbance.schedule is not None:
        if controller is None or not hasattr(controller, 'velocity_command'):
            raise ValueError('a long walk\'s changing commands need a learned policy\'s controller')
        controller = ScheduledCommand(controller, disturbance.schedule)

    def step(world, m):
        probe(world, m)
        if on_step is not None:
            on_step(world, m)
    return probe, controller, step


def gait_run(world: World, gait, duration_s: float) -> dict:
    """:func:`run_trajectory`'s world and controller for C_bal walking ``gait`` (robot/controllers
    ``GaitConfig``) in ``world`` for a run of up to ``duration_s`` [s] (extensions included): its
    walk planned as :func:`run_trajectory` plans its default one."""
    from fall_predictor.profiles.profile import C_BAL
    return {'world': world, 'controller': make_controller(
        world.profile, C_BAL, dt_s=world.dt_s, walk_duration_s=duration_s + WALK_MARGIN_S, gait=gait)}

