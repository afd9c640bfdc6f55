"""Generate push-trajectory datasets: simulate, record each trajectory as a bag, index it.

Generation is deterministic per seed (trajectory ``i`` draws its push from ``(seed, i)``
alone) and resumable: a bag is written under a temporary name and renamed when complete, and
its index row is written after that, so an interrupted run never leaves a half-written
trajectory that looks finished; a rerun skips finished trajectories and redoes unfinished ones.

The simulator (:mod:`fall_predictor.sim`) is imported inside the functions that need it, so
reading a dataset never loads PyBullet.
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from dataclasses import asdict, dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional

import numpy as np

from fall_predictor.profiles.profile import DEFAULT_ROBOT, load_profile, profile_reference
from fall_predictor.profiles.profile import C_BAL
from fall_predictor.data.bag_writer import BagWriter
from fall_predictor.data.dataset import (CAUSE_WALK, FORMAT, DatasetError, IndexRow, read_index,
                                         trajectory_id, write_index_csv)
from fall_predictor.data.dataset_writer import (StopRequested, WriterStopped, commit_section,
                                                stop_on_signals, writer_lock)
from fall_predictor.data.disturbance_generation import (causes_manifest, disturbed_run, randomization_fields,
                                                        run_cause, run_randomization, sensor_params,
                                                        undisturbed_fall_fields)
from fall_predictor.data.generation_cost import (COSTS_DIR, GENERATION_COST_KEY,
                                                 record_generation_cost, trajectory_cost)
from fall_predictor.data.outcomes import height_drop_time, unsettled_at_horizon
from fall_predictor.data.sensorbag import (write_robot_description, write_sensor_message,
                                           write_sensor_params)
from fall_predictor.data.parallel import (PerThread, compute_backend, compute_parallel, machine,
                                          progress_bar)
from fall_predictor.monitor.fileio import atomic_write_text
from fall_predictor.monitor.records import PushSpec

if TYPE_CHECKING:
    from fall_predictor.sim.pushes import PushDistribution


def _default_push_distribution() -> PushDistribution:
    from fall_predictor.sim.pushes import PushDistribution
    return PushDistribution()


def simulated_robot(robot: str = DEFAULT_ROBOT, c_bal: bool = True) -> dict[str, Any]:
    """What a dataset records about the simulated robot (the capture-point baseline needs its
    mass; its name is its profile's), with C_bal's drive settings when C_bal walks it. A robot
    given by its profile file, not a shipped profile's name, also records that file's absolute
    path: the offline tools estimate its state with that profile (:func:`dataset_robot`)."""
    from fall_predictor.sim.trajectory import ROBOT_CONTROL
    profile = load_profile(robot)
    reference = profile_reference(robot)
    return {'name': profile.name, 'total_mass_kg': profile.total_mass_kg,
            **({'profile': reference} if Path(reference).is_absolute() else {}),
            **(ROBOT_CONTROL if c_bal else {})}


@dataclass(frozen=True)
class GenerationConfig:
    seed: int
    #: Simulated time after the push ends; a trajectory that has not fallen by then counts as
    #: balanced. Justified by the calibration data (docs/results.md).
    horizon_after_push_s: float = 4.0
    #: A trajectory still moving at the horizon (:func:`~fall_predictor.data.outcomes.unsettled_at_horizon`
    #: on the simulator's state) is simulated on until it settles or falls, for up to this much
    #: longer [s] (method §4): a robot cut off mid-fall is not a balanced one.
    settle_extension_s: float = 3.0
    #: Walking recorded before the push onset (the simulation itself starts from standing).
    pre_push_s: float = 1.0
    joint_state_rate_hz: float = 100.0
    push_distribution: PushDistribution = field(default_factory=_default_push_distribution)
    #: Each trajectory draws its gait (method §3 amendment); False walks the one default gait,
    #: simulated once per worker and shared through snapshots.
    gait_variety: bool = True
    #: Record the robot's sensor topics (sim/sensors.py model at this noise scale; 1 kHz
    #: /joint_states instead of the exact ones); None records none (data/sensorbag.py).
    sensor_noise_scale: Optional[float] = None
    #: How the robot's drivers publish the sensors (sim/drivers.py ``DriverTiming`` fields:
    #: rates, stamp offsets, split joint states; simulation-time stamps); None: the simulator's
    #: own timing (every stream at 1 kHz, one stamp per step).
    sensor_timing: Optional[dict] = None
    #: The simulated robot: a robot profile's name (or path).
    robot: str = DEFAULT_ROBOT
    #: The walking controller: None or 'c_bal' (the package's C_bal), or a learned policy the
    #: robot's profile names (its push range and commanded velocities replace the gait draws).
    controller: Optional[str] = None
    #: The simulator: None (PyBullet, the datasets made before MuJoCo) or 'pybullet' / 'mujoco'.
    simulator: Optional[str] = None
    #: The causes its runs draw, (name, weight) pairs (data/disturbance_generation.py); None:
    #: pushes only, the datasets made before other causes.
    causes: Optional[tuple[tuple[str, float], ...]] = None
    #: A long walk's length [s] (the cause 'walk').
    walk_s: float = 60.0
    #: Each run's world randomised (sim/randomization.py, legged_gym-style ranges), its draw in
    #: the index; False: the nominal world, as datasets made before.
    randomize: bool = False
    #: The pushes' force range [N], (low, high), drawn instead of the robot profile's
    #: (``push_force_n``, or ``controllers.<name>.push_force_n`` for a learned policy); None: the
    #: profile's. A second sampler of the same robot (e.g. only the ambiguous band's pushes), to
    #: check a model's false-alarm budget on runs drawn otherwise (method §11, "A budget that
    #: holds"). Other causes keep their ranges.
    push_force_n: Optional[tuple[float, float]] = None

    def __post_init__(self) -> None:
        if self.push_force_n is not None:
            from fall_predictor.sim.pushes import checked_force_range
            object.__setattr__(self, 'push_force_n', checked_force_range(*self.push_force_n))

    @property
    def policy(self):
        """The learned policy's profile entry (profiles/controller_entries.py), or None for C_bal;
        its push range ``push_force_n`` when given. Read from the profile by each worker, so the
        override travels with this config."""
        if self.controller in (None, C_BAL):
            return None
        policy = load_profile(self.robot).controller_profile(self.controller)
        return policy if self.push_force_n is None else replace(policy, push_force_n=self.push_force_n)

    @property
    def pushes(self) -> PushDistribution:
        """C_bal's push distribution: ``push_distribution`` with the force range ``push_force_n``
        when given."""
        if self.push_force_n is None:
            return self.push_distribution
        return replace(self.push_distribution, force_n=self.push_force_n)

    def manifest(self) -> dict:
        out = {'format': FORMAT, 'seed': self.seed, 'horizon_after_push_s': self.horizon_after_push_s,
               'settle_extension_s': self.settle_extension_s,
               'pre_push_s': self.pre_push_s, 'joint_state_rate_hz': self.joint_state_rate_hz,
               'gait_variety': self.gait_variety,
               'push_distribution': asdict(self.pushes),
               'robot': simulated_robot(self.robot, self.policy is None)}
        if self.sensor_noise_scale is not None:
            from fall_predictor.sim.sensors import SensorParams
            out['sensors'] = SensorParams(noise_scale=self.sensor_noise_scale).to_dict()
            if self.sensor_timing is not None:
                out['sensor_timing'] = self.timing().to_dict()
        if self.simulator not in (None, 'pybullet'):
            out['simulator'] = self.simulator
        if self.causes is not None:
            out.update(causes_manifest(self))
        if self.randomize:
            from fall_predictor.sim.randomization import RandomizationRanges
            out['randomization'] = RandomizationRanges().to_dict()
        policy = self.policy
        if policy is not None:
            # The run's draws are the policy's: the gait fields say nothing of it.
            out['simulator'] = self.simulator or load_profile(self.robot).simulator
            from fall_predictor.sim.policy_runs import commanded_pushes, policy_manifest
            out['controller'] = policy_manifest(policy)
            out['push_distribution'] = commanded_pushes(policy).manifest()
            del out['gait_variety']
        return out

    def timing(self):
        """The drivers' timing of the sensor topics (:class:`fall_predictor.sim.drivers.DriverTiming`)."""
        from fall_predictor.sim.drivers import DriverTiming
        return DriverTiming.from_dict(self.sensor_timing or {})


def _settings(manifest: dict) -> dict:
    """The generation settings of a manifest (what a resumed run must match): all but the
    cost record, which every run updates."""
    return {k: v for k, v in manifest.items() if k != GENERATION_COST_KEY}


def _open_dataset(out: Path, config: GenerationConfig) -> None:
    manifest_path = out / 'dataset.json'
    manifest = json.loads(json.dumps(config.manifest()))   # as it reads back from the file
    if manifest_path.exists():
        try:
            existing = json.loads(manifest_path.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise DatasetError(f'{manifest_path}: unreadable manifest: {exc}') from exc
        existing = _settings(existing)
        if existing != manifest:
            differ = sorted(k for k in set(existing) | set(manifest) if existing.get(k) != manifest.get(k))
            said = '; '.join(f'{k}: {existing.get(k)} there, {manifest.get(k)} now' for k in differ)
            raise DatasetError(f'{out}: exists with different generation settings ({said}); use '
                               'another --out or the same settings')
    else:
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(manifest_path, json.dumps(manifest, indent=1, sort_keys=True))
    for sub in ('bags', 'index', COSTS_DIR):
        (out / sub).mkdir(exist_ok=True)


#: Per worker thread: its simulator, or its simulated default walk (PyBullet worlds are not
#: shared between threads).
_WORKER = PerThread()


def _walk_prefix(config: GenerationConfig):
    """The robot's unpushed walk (its profile's gait) up to the latest possible push onset,
    simulated once per worker thread (trajectories then start from its snapshots; each depends only
    on its own push, not on the worker's earlier ones:
    :meth:`~fall_predictor.sim.pybullet_world.PybulletWorld.restore`)."""
    from fall_predictor.sim.pushes import robot_gait
    from fall_predictor.sim.trajectory import WalkPrefix
    from fall_predictor.sim.world import make_world

    dist = config.pushes
    cycle_s = dist.walk_cycle_s(robot_gait(config.robot))
    until = dist.settle_s + cycle_s
    record = config.sensor_noise_scale is not None
    # The prefix owns a world of its own: a run of another cause starts the worker's world again
    # (with its terrain), which would void the prefix's snapshots.
    return _WORKER.get(('prefix', config.robot, config.simulator, dist.settle_s, cycle_s, record),
                       lambda: WalkPrefix(make_world(load_profile(config.robot), config.simulator or 'pybullet'),
                                          until_s=until,
                                          walk_duration_s=(until + config.horizon_after_push_s
                                                           + config.settle_extension_s + 5.0),
                                          record_sensors=record))


def _worker_simulator(robot: str = DEFAULT_ROBOT, simulator: Optional[str] = None,
                      dt_s: Optional[float] = None):
    """One world per worker thread, robot, simulator and step, started again for every
    trajectory (PyBullet by default)."""
    from fall_predictor.sim.world import make_world
    return _WORKER.get(('simulator', robot, simulator, dt_s),
                       lambda: make_world(load_profile(robot), simulator or 'pybullet', dt_s))


def _worker_policy(config: 'GenerationConfig'):
    """One learned policy per worker thread and deploy config (its network read once)."""
    from fall_predictor.sim.policy_runs import load_learned_policy
    return _WORKER.get(('policy', str(config.policy.policy_path)),
                       lambda: load_learned_policy(config.policy))


def _policy_start(config: 'GenerationConfig', index: int, rng) -> tuple:
    """A learned policy's run: (its command, its push, run_trajectory's arguments: the world,
    the policy walking at the command, the live sensor model seeded as the bag's readings)."""
    from fall_predictor.sim.policy_runs import commanded_pushes
    command, push = commanded_pushes(config.policy).sample(rng)
    return command, push, _policy_arguments(config, index, command)


def _policy_arguments(config: 'GenerationConfig', index: int, command) -> dict:
    """run_trajectory's arguments of run ``index`` of a learned policy walking at ``command``."""
    from fall_predictor.sim.policy_runs import policy_run
    learned = _worker_policy(config)
    profile = load_profile(config.robot)
    world = _worker_simulator(config.robot, config.simulator or profile.simulator,
                              learned.physics_dt_s)
    noise = 1.0 if config.sensor_noise_scale is None else config.sensor_noise_scale
    return policy_run(profile, config.policy, learned, command, noise, _sensor_seed(config, index), world,
                      sensor_params(config, index, noise))


def _sensor_seed(config: 'GenerationConfig', index: int) -> int:
    """The seed of trajectory ``index``'s sensor noise."""
    return int(np.random.SeedSequence([config.seed, index, 10]).generate_state(1)[0])


def _command_fields(command) -> dict:
    if command is None:
        return {}
    return {'command_vx_m_s': round(command[0], 6), 'command_vy_m_s': round(command[1], 6),
            'command_yaw_rate_rad_s': round(command[2], 6)}


def _gait_fields(gait) -> dict:
    if gait is None:
        return {}
    speed = gait.step_length_m / (gait.single_support_s + gait.double_support_s)
    return {'gait_speed_m_s': round(speed, 6), 'gait_single_support_s': round(gait.single_support_s, 6),
            'gait_step_width_m': round(2 * gait.stance_half_width_m, 6), 'gait_standing': gait.standing}


@dataclass
class SimulatedTrajectory:
    """What a worker sends back for one trajectory: its index row, its bag as the bytes of its
    files (name -> content), and what it cost (:func:`trajectory_cost`)."""

    row: IndexRow
    bag_files: dict[str, bytes]
    cost: dict[str, Any]


def simulate_one(config: GenerationConfig, index: int) -> SimulatedTrajectory:
    """Simulate trajectory ``index`` and record it as a bag in a private temporary directory;
    return the bag's bytes. Writes nothing else, so it runs anywhere (a Dask worker included)."""
    from fall_predictor.sim.drivers import DriverStreams
    from fall_predictor.sim.pushes import robot_gait, trajectory_seed
    from fall_predictor.sim.trajectory import gait_run, run_trajectory


    cpu0, wall0 = time.thread_time(), time.perf_counter()
    tid = trajectory_id(index)
    rng = trajectory_seed(config.seed, index)
    command = None
    cause = run_cause(config.causes, config.seed, index)
    if cause != 'push':
        world, start = ((_worker_simulator(config.robot, config.simulator), None) if config.policy is None
                        else (None, partial(_policy_arguments, config, index)))
        push, result, t_start, gait, command, cause_fields = disturbed_run(
            config, index, cause, world, start, _still_moving, run_randomization(config, index))
    elif config.policy is not None:
        gait = None
        command, push, start = _policy_start(config, index, rng)
    elif config.gait_variety:
        gait, push = config.pushes.sample_with_gait(rng)
        start = gait_run(_worker_simulator(config.robot, config.simulator), gait,
                         push.t_force_end + config.horizon_after_push_s + config.settle_extension_s)
    else:
        gait, push = None, config.pushes.sample(rng, robot_gait(config.robot))
        start = ({'prefix': _walk_prefix(config)} if not config.randomize else gait_run(
            _worker_simulator(config.robot, config.simulator), robot_gait(config.robot),
            push.t_force_end + config.horizon_after_push_s + config.settle_extension_s))
    if cause == 'push':
        t_start = round(push.t_push - config.pre_push_s, 6)
        mass_kg = load_profile(config.robot).total_mass_kg
        result = run_trajectory(push, push.t_force_end + config.horizon_after_push_s,
                                record_sensors=config.sensor_noise_scale is not None,
                                go_on_while=partial(_still_moving, push.t_push, t_start, mass_kg),
                                max_extension_s=config.settle_extension_s,
                                randomization=run_randomization(config, index), **start)
        cause_fields = {} if config.causes is None else {'t_onset': push.t_push}
    if result.fallen and result.t_fallen < push.t_push:
        # It fell before its disturbance acted (a randomised world it cannot walk in): an
        # undisturbed walk that fell, recorded from its start; a walk that fell counts as a fall
        # like any other (method §5), not as the disturbance's.
        cause_fields = undisturbed_fall_fields(cause, push, cause_fields)
        cause, t_start, push = CAUSE_WALK, 0.0, PushSpec(0.0, 0.0, 0.0, 0.0, 0.0)
    cause_fields.update(randomization_fields(config, index))
    simulated_s = result.measurements[-1].t
    first = next(i for i, m in enumerate(result.measurements) if m.t >= t_start - 1e-9)
    measurements = result.measurements[first:]
    t_height_drop = None
    if result.fallen:
        t = np.array([m.t for m in measurements])
        z = np.array([m.com[2] for m in measurements])
        t_height_drop = height_drop_time(t, z, result.t_fallen)
    joint_every = max(1, int(round(1.0 / (config.joint_state_rate_hz * 0.001))))
    with tempfile.TemporaryDirectory(prefix='fall_predictor_bag_') as folder:
        # The bag's own directory name is the one it is renamed from when committed
        # (metadata.yaml names the MCAP file relative to it, so the files do not change).
        unfinished = Path(folder) / (tid + '.partial')
        with BagWriter(unfinished) as bag:
            if cause == 'push':
                applied = next((m.push_force for m in measurements if m.push_force.any()), np.zeros(3))
                bag.write_push(push.t_push, applied)
            readings = _sensor_readings(config, index, result, bag, first)
            drivers = None if readings is None else DriverStreams(config.timing())
            for k, m in enumerate(measurements):
                bag.write_measurement(m)
                if drivers is not None:
                    for stream, reading in drivers.push(readings[first + k]):
                        write_sensor_message(bag, stream, reading)
                elif k % joint_every == 0:
                    i = first + k
                    bag.write_joint_state(m.t, load_profile(config.robot).joint_names,
                                          result.joint_positions[i],
                                          result.joint_velocities[i])
        files = {f.name: f.read_bytes() for f in sorted(unfinished.iterdir())}
    row = IndexRow(trajectory_id=tid, bag=f'bags/{tid}', force_n=push.force_n, angle_deg=push.angle_deg,
                   height_m=push.height_m, t_push=push.t_push, t_force_end=push.t_force_end,
                   fallen=result.fallen, t_fallen=result.t_fallen, t_height_drop=t_height_drop,
                   t_reflex=result.t_reflex, t_start=measurements[0].t, t_end=measurements[-1].t,
                   samples=len(measurements), **_gait_fields(gait), **_command_fields(command),
                   **cause_fields)
    cost = trajectory_cost(time.thread_time() - cpu0, time.perf_counter() - wall0, simulated_s)
    return SimulatedTrajectory(row, files, cost)


def _still_moving(t_push: float, t_start: float, mass_kg: float, measurements: list) -> bool:
    """Whether a run's recording so far (from ``t_start``) ends unsettled (the loader's test,
    :func:`~fall_predictor.data.outcomes.unsettled_at_horizon`, on the simulator's state)."""
    first = next(i for i, m in enumerate(measurements) if m.t >= t_start - 1e-9)
    recorded = measurements[first:]
    t = np.fromiter((m.t for m in recorded), float, len(recorded))
    momentum = np.array([m.lin_mom[:2] for m in recorded])
    return unsettled_at_horizon(t, momentum, t_push, mass_kg) is not None


def _sensor_readings(config: GenerationConfig, index: int, result, bag: BagWriter, first: int):
    """The run's sensor readings (noise seeded by dataset seed and index), with the sensor
    parameters and the robot description written into ``bag``; None without sensors."""
    if config.sensor_noise_scale is None:
        return None
    from fall_predictor.sim.sensors import apply_sensors, robot_description

    params = sensor_params(config, index, config.sensor_noise_scale)
    write_sensor_params(bag, {**params.to_dict(), 'timing': config.timing().to_dict()})
    profile = load_profile(config.robot)
    write_robot_description(bag, result.measurements[first].t, robot_description(profile))
    if result.sensor_readings:
        return result.sensor_readings       # made as the run went: what its controller saw
    return apply_sensors(result.sensor_truths, params, seed=_sensor_seed(config, index),
                         profile=profile)


def commit(out: Path, simulated: SimulatedTrajectory) -> IndexRow:
    """Write a simulated trajectory into dataset ``out``: its bag (under a temporary name,
    renamed when complete), its cost record, and last its index row, which marks it finished."""
    tid = simulated.row.trajectory_id
    final = out / 'bags' / tid
    partial = out / 'bags' / (tid + '.partial')
    shutil.rmtree(partial, ignore_errors=True)
    shutil.rmtree(final, ignore_errors=True)
    partial.mkdir(parents=True)
    for name, content in simulated.bag_files.items():
        (partial / name).write_bytes(content)
    os.replace(partial, final)
    atomic_write_text(out / COSTS_DIR / f'{tid}.json', json.dumps(simulated.cost, sort_keys=True))
    atomic_write_text(out / 'index' / f'{tid}.json', json.dumps(asdict(simulated.row), sort_keys=True))
    return simulated.row


def generate_one(out: Path, config: GenerationConfig, index: int) -> IndexRow:
    """Simulate trajectory ``index`` and write its bag and index row (atomically)."""
    return commit(out, simulate_one(config, index))


def _finished(out: Path, index: int) -> bool:
    tid = trajectory_id(index)
    return (out / 'index' / f'{tid}.json').exists() and (out / 'bags' / tid / 'metadata.yaml').exists()


def generate_dataset(out: str | os.PathLike, trajectories: int, seed: int, jobs: int = 1,
                     config: Optional[GenerationConfig] = None, progress: bool = True,
                     scheduler: Optional[str] = None) -> list[IndexRow]:
    """Generate (or finish generating) ``trajectories`` push trajectories into ``out``.

    Trajectories are simulated by ``jobs`` local processes, or by the workers of the Dask
    cluster whose scheduler is at ``scheduler`` (:mod:`fall_predictor.data.parallel`); either
    way this process writes every bag into ``out`` as it arrives, so ``out`` need not be shared
    with the workers. The result does not depend on where, in which order or by how many
    processes the trajectories were simulated. ``dataset.json`` records the CPU time and the
    machines that simulated them (:func:`generation_cost`).
    """
    out = Path(out)
    config = config or GenerationConfig(seed=seed)
    if config.seed != seed:
        raise ValueError('seed and config.seed differ')
    out.mkdir(parents=True, exist_ok=True)
    with writer_lock(out, 'generate'), stop_on_signals():
        _open_dataset(out, config)
        return _generate_locked(out, trajectories, config, jobs, progress, scheduler)


def _generate_locked(out: Path, trajectories: int, config: GenerationConfig, jobs: int,
                     progress: bool, scheduler: Optional[str]) -> list[IndexRow]:
    """:func:`generate_dataset` holding the dataset's writer lock: a stop (SIGINT, SIGTERM) ends
    between two commits, as :class:`~fall_predictor.data.dataset_writer.WriterStopped` saying how
    far it got."""
    from joblib import delayed

    pending = [i for i in range(trajectories) if not _finished(out, i)]
    started, wall0 = time.time(), time.perf_counter()
    bar = progress_bar(trajectories, trajectories - len(pending), disable=not progress)
    cpu_s, committed = 0.0, 0
    try:
        if pending:
            with compute_backend(scheduler):
                results = compute_parallel(jobs, return_as='generator_unordered')(
                    delayed(simulate_one)(config, i) for i in pending)
                for simulated in results:
                    with commit_section():
                        commit(out, simulated)
                        committed += 1
                    cpu_s += simulated.cost['cpu_s']
                    bar.set_postfix_str(f'CPU {cpu_s:.0f} s', refresh=False)
                    bar.update(1)
    except StopRequested as stop:
        raise WriterStopped(stop.signum, out, committed,
                                trajectories - len(pending) + committed, trajectories) from None
    finally:
        bar.close()
        run = {'started_utc': time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime(started)),
               'wall_s': round(time.perf_counter() - wall0, 3), 'simulated_trajectories': committed,
               'jobs': jobs, 'scheduler': scheduler, 'client': machine()}
        with commit_section():
            record_generation_cost(out, run)
    rows = read_index(out)
    write_index_csv(out, rows)
    return rows
