"""Bring-up of the onboard fall monitor: start the nodes as processes and push the robot N times.

:func:`run_bringup` starts the simulator, controller, feature and predictor nodes (and
optionally the recorder) as separate processes (``python -m fall_predictor.ros.<node>
--ros-args --params-file ...``) on an isolated ROS domain with localhost-only discovery,
waits until they are all up and connected, then for each push:

1. resets the simulator (``/simulator_node/reset``): a fresh world at t = 0;
2. requests a push drawn from :class:`~fall_predictor.sim.pushes.PushDistribution` with the
   generator of trajectory ``i`` of a dataset with the same seed
   (:func:`~fall_predictor.sim.pushes.trajectory_seed`), so push ``i`` equals the push of
   trajectory ``i`` of ``fall-predictor generate --fixed-gait --seed S`` (with gait variety, the
   default, a trajectory draws its gait first, and so another push); the onset (2.1 to 3.5 s
   into the walk) is the request's stamp. Under a learned policy (``controller``, default the
   robot profile's) push ``i`` and the velocity command it walks at are those of dataset
   trajectory ``i`` (:func:`~fall_predictor.sim.policy_runs.commanded_pushes`, drawn as
   ``generate`` draws them); the command is set on the controller node before the reset;
3. follows ``/fall_predictor/measurement`` (fallen flag), ``/fall_predictor/state`` and
   ``/fall_predictor/controller_mode`` until the robot is fallen or ``horizon_s`` of
   simulation time after the push ended, then pauses the simulator (``~/pause``), so that a
   recorded run ends there;
4. reports one JSON object (printed as one line when ``json_out`` is given), with the robot,
   its controller, its simulator and the velocity command (null under C_bal).

A learned policy walks on the robot's sensor topics, so it runs only with ``sensors`` (the
monitor on the state estimator's measurement): with ``--true-state`` the bring-up refuses it in
words rather than give the policy or the monitor another input than the robot's.

After a predicted fall C_fall freezes the robot, which may then stay up: ``fell`` is false and
``t_fallen`` null, and ``outcome`` says ``predicted_no_fall``. Outcomes: ``fall_predicted``
(fallen, first falling state at or after the push and no later than fallen), ``fall_missed``
(fallen without such a prediction), ``predicted_no_fall``, ``no_fall`` (no prediction, not
fallen). ``stopped_by`` is ``fallen`` or ``horizon``. ``degraded_states`` counts the run's
states without a prediction (degraded or stale) and ``degraded_reasons`` says why: each kind of
reason in the state's own words, its measured values as ``#`` (a sample arriving 0.057 s and one
0.081 s late are one kind), with its count; ``degraded_reason_examples`` gives the first reason of
each kind in full. ``observer_lost_samples`` counts the measurements the bring-up's own observer
missed (its queue of 1000 overflows if it lags a second of simulation behind, on a saturated
machine): ``t_fallen`` is then late by up to the gap that hid the fall (the recorder counts its
own gaps in its bag's metadata).

Shutdown is ordered (simulator first, the recorder last so that it can drain) by SIGINT, then
SIGTERM, then SIGKILL after timeouts; the node processes also get SIGTERM if this process dies
(Linux ``PR_SET_PDEATHSIG``), so no orphans are left behind.

The bring-up's own ROS node is :class:`fall_predictor.ros.observer.Observer`; the command-line
options are defined in :mod:`fall_predictor.cli`, so ``fall-predictor --help`` needs no ROS.
"""
from __future__ import annotations

import argparse
import ctypes
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Optional, TextIO

from fall_predictor.contract.topics import PIPELINE_NODES, RECORDER_NODE
from fall_predictor.profiles.profile import DEFAULT_ROBOT, ProfileError, RobotProfile, load_profile
from fall_predictor.sim.world import SIMULATORS
from fall_predictor.ros.errors import BringupError
from fall_predictor.ros.share import package_share_dir

if TYPE_CHECKING:
    from fall_predictor.profiles.profile import PolicyControllerProfile
    from fall_predictor.sim.pushes import PushDistribution

#: Shutdown order: the source of all samples first, the recorder last.
SHUTDOWN_ORDER = ('simulator_node', 'state_estimator_node', 'controller_node', 'feature_node',
                  'predictor_node', RECORDER_NODE)
#: With ``sensors``: the node that turns the simulator's sensor topics into the measurement.
ESTIMATOR_NODE = 'state_estimator_node'



# --------------------------------------------------------------------------------------------
# Processes
# --------------------------------------------------------------------------------------------

def _die_with_parent() -> None:  # pragma: no cover - runs in the child between fork and exec
    """Ask Linux to send SIGTERM to this child when the bring-up process dies."""
    pr_set_pdeathsig = 1
    ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, signal.SIGTERM)


def ros_environment(domain_id: int) -> dict[str, str]:
    """The environment of a node process: isolated domain, localhost-only discovery."""
    env = dict(os.environ)
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.pop('ROS_LOCALHOST_ONLY', None)         # deprecated in Jazzy, superseded by the above
    env.pop('ROS_STATIC_PEERS', None)
    env['PYTHONUNBUFFERED'] = '1'
    return env


@contextmanager
def _scoped_environment(values: dict[str, str]) -> Iterator[None]:
    saved = {key: os.environ.get(key) for key in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


@dataclass
class NodeProcess:
    """One node running as a child process, its output in ``log_path``."""

    name: str
    process: subprocess.Popen
    log_path: Path

    def log_tail(self, lines: int = 15) -> str:
        try:
            text = self.log_path.read_text(errors='replace')
        except OSError:
            return ''
        return '\n'.join(text.splitlines()[-lines:])


def node_command(name: str, params_file: Path, overrides: dict[str, str]) -> list[str]:
    """``python -m fall_predictor.ros.<name> --ros-args --params-file F -p k:=v ...``."""
    command = [sys.executable, '-m', f'fall_predictor.ros.{name}', '--ros-args',
               '--params-file', str(params_file)]
    for key, value in overrides.items():
        command += ['-p', f'{key}:={value}']
    return command


def start_process(name: str, command: list[str], env: dict[str, str],
                  log_dir: Path) -> NodeProcess:
    """Start ``command`` in its own session (so that a terminal's Ctrl-C reaches only the
    bring-up, which then stops the nodes in order), dying with this process, output to
    ``log_dir/<name>.log``."""
    log_path = log_dir / f'{name}.log'
    # faulthandler: a node that has to be aborted (see stop_nodes) leaves its Python stacks in
    # its log, so a hang can be diagnosed after the fact.
    env = {**env, 'PYTHONFAULTHANDLER': '1'}
    with open(log_path, 'wb') as log:
        process = subprocess.Popen(
            command, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, env=env,
            start_new_session=True,
            preexec_fn=_die_with_parent if sys.platform.startswith('linux') else None)
    return NodeProcess(name, process, log_path)


def start_node(name: str, params_file: Path, overrides: dict[str, str], env: dict[str, str],
               log_dir: Path) -> NodeProcess:
    """Start node module ``name`` (see :func:`node_command`, :func:`start_process`)."""
    return start_process(name, node_command(name, params_file, overrides), env, log_dir)


#: What a node that outlives SIGINT gets next, each after ``term_timeout_s``.
_ESCALATION = (signal.SIGTERM, signal.SIGABRT, signal.SIGKILL)


def stop_nodes(nodes: dict[str, NodeProcess], sigint_timeout_s: float = 10.0,
               term_timeout_s: float = 3.0, recorder_drain_s: float = 1.0) -> dict[str, int]:
    """Stop the nodes in :data:`SHUTDOWN_ORDER`: SIGINT and wait, then SIGTERM, then SIGABRT
    (the node's Python stacks go to its log: :func:`start_process` enables faulthandler),
    then SIGKILL.

    The recorder is stopped ``recorder_drain_s`` after the others so that it receives what
    they published last. Returns the exit code of every process (-6 or -9: it hung).
    """
    for name in SHUTDOWN_ORDER:
        node = nodes.get(name)
        if node is None or node.process.poll() is not None:
            continue
        if name == RECORDER_NODE:
            time.sleep(recorder_drain_s)
        node.process.send_signal(signal.SIGINT)
        if name == 'simulator_node':
            _wait(node.process, sigint_timeout_s)
    for node in nodes.values():
        timeout_s = sigint_timeout_s
        for escalation in _ESCALATION:
            if _wait(node.process, timeout_s) is not None:
                break
            node.process.send_signal(escalation)
            timeout_s = term_timeout_s
        else:
            node.process.wait()
    return {name: node.process.returncode for name, node in nodes.items()}


def _wait(process: subprocess.Popen, timeout_s: float) -> Optional[int]:
    try:
        return process.wait(timeout_s)
    except subprocess.TimeoutExpired:
        return None


# --------------------------------------------------------------------------------------------
# The bring-up
# --------------------------------------------------------------------------------------------

def default_params_file() -> Path:
    """``config/fall_predictor.yaml`` of the installed package or of the source tree."""
    return package_share_dir() / 'config' / 'fall_predictor.yaml'


def default_domain_id() -> int:
    """A domain id derived from the process id, away from the default domain 0."""
    return 100 + os.getpid() % 100


#: The predictor's parameters in an unpaced run (``real_time_factor`` 0). Simulation time then
#: runs as fast as the lock-stepped simulator and controller go, not with wall time, and the
#: simulator does not wait for the predictor: on a busy machine the predictor falls tens of
#: simulated milliseconds behind ``/clock`` (which it takes keep-last 1, so it jumps ahead of the
#: queued samples) and its sample-age check would answer STALE for samples late only in
#: simulated time, a fall predicted later or not at all by the machine's load. A paced run
#: keeps the check: its simulated time is wall time.
UNPACED_PREDICTOR_PARAMS = {'max_sample_age_s': '0.0'}


def node_overrides(real_time_factor: float, model_path: Optional[Path], fall_trigger: bool,
                   sensors: bool, sensor_timing: str, robot: str, record_dir: Optional[Path],
                   controller: Optional[str] = None, simulator: Optional[str] = None
                   ) -> tuple[list[str], dict[str, dict[str, str]]]:
    """The nodes a bring-up starts, in order, and each one's parameter overrides (strings, as
    on the command line); the arguments are :func:`run_bringup`'s, ``model_path`` resolved."""
    profile = load_profile(robot)
    policy = profile.controller_profile(controller)
    overrides: dict[str, dict[str, str]] = {
        'simulator_node': {'real_time_factor': repr(float(real_time_factor)),
                           'autostart': 'false', 'lockstep': 'true'},
        # Both read the model: the feature node for the feature settings it was trained with.
        'predictor_node': {'model_path': str(Path(model_path).resolve())} if model_path else {},
        'feature_node': {'model_path': str(Path(model_path).resolve())} if model_path else {},
        'controller_node': {} if fall_trigger else {'fall_trigger_enabled': 'false'},
    }
    if robot != DEFAULT_ROBOT:
        for name in ('simulator_node', 'feature_node', 'predictor_node', 'controller_node'):
            overrides[name]['robot'] = robot
    for name in ('simulator_node', 'controller_node'):
        overrides[name].update({k: v for k, v in (('controller', controller),
                                                  ('simulator', simulator)) if v})
    names = list(PIPELINE_NODES)
    if sensors:
        overrides['simulator_node']['publish_sensors'] = 'true'
        if policy is None:      # C_bal, the robot's own controller, on the exact state
            overrides['controller_node']['ground_truth'] = 'true'
        if sensor_timing == 'robot':            # sim/drivers.DriverTiming.robot(500 Hz, split)
            overrides['simulator_node'].update(
                sensor_joint_rate_hz='500.0', sensor_imu_offset_s='0.0003',
                sensor_wrench_offset_s='0.0004', sensor_split_joints='true')
            legs = profile.legs_and_upper_body()[0]
            overrides[ESTIMATOR_NODE] = {'driving_joints': '[' + ', '.join(f'"{j}"' for j in legs) + ']'}
        overrides.setdefault(ESTIMATOR_NODE, {})
        if robot != DEFAULT_ROBOT:
            overrides[ESTIMATOR_NODE]['robot'] = robot
        names.insert(names.index('simulator_node'), ESTIMATOR_NODE)
    if record_dir is not None:
        names.insert(0, RECORDER_NODE)
        overrides[RECORDER_NODE] = {'bag_path': str(Path(record_dir).resolve())}
    if real_time_factor == 0.0:
        overrides['predictor_node'].update(UNPACED_PREDICTOR_PARAMS)
    return names, overrides


def run_bringup(pushes: int, seed: int, json_out: Optional[TextIO] = None,
                domain_id: Optional[int] = None, real_time_factor: Optional[float] = None,
                model_path: Optional[Path] = None, params_file: Optional[Path] = None,
                record_dir: Optional[Path] = None, horizon_s: float = 3.0,
                log_dir: Optional[Path] = None, startup_timeout_s: float = 60.0,
                push_distribution: Optional[PushDistribution] = None,
                fall_trigger: bool = True, sensors: Optional[bool] = None,
                sensor_timing: str = 'simulator', robot: str = DEFAULT_ROBOT,
                controller: Optional[str] = None, simulator: Optional[str] = None) -> list[dict]:
    """Start the nodes, push the robot ``pushes`` times, stop everything; see the module docs.

    ``real_time_factor`` 0 runs as fast as the lock-stepped simulator and controller go (the
    predictor's sample-age check is then off, :data:`UNPACED_PREDICTOR_PARAMS`); the monitor is
    not lock-stepped, so this is the default only where the simulator is the slower (C_bal in
    PyBullet): a learned policy in MuJoCo outpaces it, and its runs default to 1 (real time, as
    on the robot); ``record_dir`` also runs the recorder (one bag per push run);
    ``horizon_s`` is the simulation time [s] watched after a push ends if the robot does not
    fall; node logs go to ``log_dir`` (default: a new temporary directory);
    ``push_distribution`` defaults to method §3's (under a learned policy: its datasets' protocol,
    whose ``sample(rng)`` gives the velocity command and the push). With ``fall_trigger`` false
    the predictor still runs and is reported, but the walking controller stays in charge
    throughout (method §4: the recording then carries valid hindsight labels for training). With
    ``sensors`` the simulator publishes the robot's sensor topics and its exact state on
    ``/fall_predictor/ground_truth``, and the state_estimator_node makes the measurement the
    other nodes read (None: with sensors under a learned policy or on another robot than the
    default, with the exact state for C_bal on the default robot; false under a learned policy is
    refused). ``robot`` (a robot profile) is the simulated robot; another robot than the default
    runs with sensors, its push range and its profile's shipped model for the controller.
    ``controller`` and ``simulator`` default to the profile's. Raises :class:`BringupError` if
    the controller cannot run so, the model is missing, a node fails to start or dies, or the
    simulation gets stuck.
    """
    if pushes < 0:
        raise ValueError(f'pushes must be >= 0, got {pushes}')
    import rclpy

    from fall_predictor.ros.observer import Observer
    from fall_predictor.sim.pushes import PushDistribution, robot_gait, trajectory_seed

    profile = load_profile(robot)
    controller, simulator, policy = _controller_of(profile, controller, simulator, sensors)
    if robot != DEFAULT_ROBOT or policy is not None:
        sensors = True                  # the monitor on the robot's own sensor topics
        if policy is None:
            push_distribution = push_distribution or PushDistribution.for_robot(profile)
        if model_path is None:
            model_path = _shipped_model(profile, controller)
    sensors = bool(sensors)
    if real_time_factor is None:
        real_time_factor = 0.0 if policy is None else 1.0
    if policy is not None and push_distribution is None:
        from fall_predictor.sim.policy_runs import commanded_pushes
        push_distribution = commanded_pushes(policy)
    push_distribution = push_distribution or PushDistribution()
    domain_id = default_domain_id() if domain_id is None else domain_id
    env = ros_environment(domain_id)
    log_dir = Path(log_dir) if log_dir else Path(tempfile.mkdtemp(prefix='fall_predictor_bringup_'))
    log_dir.mkdir(parents=True, exist_ok=True)
    params_file = Path(params_file) if params_file else default_params_file()
    names, overrides = node_overrides(real_time_factor, model_path, fall_trigger, sensors,
                                      sensor_timing, robot, record_dir, controller, simulator)

    context = rclpy.Context()
    with _scoped_environment({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}):
        rclpy.init(context=context, domain_id=domain_id)
    nodes: dict[str, NodeProcess] = {}
    observer: Optional[Observer] = None
    results: list[dict] = []
    try:
        observer = Observer(context, 'fall_predictor_bringup')
        for name in names:
            nodes[name] = start_node(name, params_file, overrides[name], env, log_dir)

        def check_alive() -> None:
            for node in nodes.values():
                code = node.process.poll()
                if code is not None:
                    raise BringupError(f'{node.name} exited with code {code} '
                                       f'(log {node.log_path}):\n{node.log_tail()}')

        if not observer.spin_until(lambda: observer.connected(names), startup_timeout_s,
                                   check_alive):
            raise BringupError(f'the nodes did not come up within {startup_timeout_s} s '
                               f'(logs in {log_dir})')
        for index in range(pushes):
            command = None
            if policy is None:
                push = push_distribution.sample(trajectory_seed(seed, index), robot_gait(robot))
            else:   # dataset trajectory i's command, set before the reset starts the run
                command, push = push_distribution.sample(trajectory_seed(seed, index))
                _command_controller(observer, command)
            result = observer.run_push(index, push, horizon_s, check_alive,
                                       profile.fallen_com_height_m)
            result.update(seed=seed, domain_id=domain_id, robot=profile.name,
                          controller=controller, simulator=simulator,
                          command=None if command is None else [float(v) for v in command])
            results.append(result)
            if json_out is not None:
                print(json.dumps(result, sort_keys=True), file=json_out, flush=True)
    finally:
        if observer is not None:
            observer.destroy()
        rclpy.try_shutdown(context=context)
        stop_nodes(nodes)
    return results


def _controller_of(profile: RobotProfile, controller: Optional[str], simulator: Optional[str],
                   sensors: Optional[bool]) -> tuple[str, str, Optional['PolicyControllerProfile']]:
    """(controller, simulator, the learned policy's profile entry or None) of the bring-up's
    options, the profile's where not given; BringupError in words for what cannot run."""
    name = controller or profile.default_controller
    try:
        policy = profile.controller_profile(name)
    except ProfileError as error:
        raise BringupError(str(error)) from None
    simulator = simulator or profile.simulator
    if simulator not in SIMULATORS:
        raise BringupError(f'simulator must be one of {", ".join(SIMULATORS)}, got {simulator!r}')
    if policy is not None and sensors is False:
        raise BringupError(f'controller {name!r} is a learned policy: it walks on the robot\'s '
                           'sensor topics, and the monitor then reads the state estimated from '
                           'them; --true-state (the monitor on the simulator\'s exact state) is '
                           'for C_bal (--controller c_bal)')
    return name, simulator, policy


def _shipped_model(profile: RobotProfile, controller: str) -> Path:
    """The package's model for ``profile``'s robot under ``controller`` (BringupError naming the
    file when it is not there)."""
    try:
        name = profile.model_for(controller)
    except ProfileError as error:
        raise BringupError(f'{error}: train one on its data and pass --model FILE') from None
    path = package_share_dir() / 'models' / name
    if not path.is_file():
        raise BringupError(f'no shipped model for robot {profile.name!r} under {controller!r}: '
                           f'{path} does not exist; generate its data (fall-predictor generate '
                           f'--robot {profile.name} --controller {controller}), train one '
                           '(fall-predictor train) and pass --model FILE')
    return path


def _command_controller(observer, command) -> None:
    """Set the controller node's velocity command (vx, vy, yaw rate) for the next run."""
    names = ('command_vx_m_s', 'command_vy_m_s', 'command_yaw_rate_rad_s')
    results = observer.set_parameters('controller_node', **{
        name: float(value) for name, value in zip(names, command)})
    refused = [r.reason for r in results if not r.successful]
    if refused:
        raise BringupError(f'controller_node refused the velocity command {list(command)}: '
                           f'{"; ".join(refused)}')


# --------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------

def cmd_bringup(args: argparse.Namespace) -> int:
    """Run :func:`run_bringup` from the parsed options of ``fall-predictor bringup``; exit code."""
    try:
        results = run_bringup(args.pushes, args.seed, sys.stdout if args.json else None,
                              domain_id=args.domain_id, real_time_factor=args.real_time_factor,
                              model_path=args.model, params_file=args.params_file,
                              record_dir=args.record, horizon_s=args.horizon,
                              log_dir=args.log_dir, fall_trigger=args.fall_trigger,
                              sensors=args.sensors, sensor_timing=args.sensor_timing,
                              robot=args.robot, controller=args.controller,
                              simulator=args.simulator)
    except BringupError as error:
        print(f'error: {error}', file=sys.stderr)
        return 1
    if not args.json:
        for r in results:
            push = r['push']
            lead = '' if r['lead_time_s'] is None else f", lead {r['lead_time_s']:.3f} s"
            walk = '' if r['command'] is None else ' walking at ({:.2f}, {:.2f}, {:.2f})'.format(
                *r['command'])
            print(f"push {r['index']}: {push['force_n']:.0f} N at {push['angle_deg']:.0f} deg, "
                  f"t = {push['t_push']:.3f} s, {r['controller']} in {r['simulator']}{walk} -> "
                  f"{r['outcome']} (predicted {r['t_predict']}, fallen {r['t_fallen']}{lead}), "
                  f"controller {r['controller_mode']}")
    return 0
