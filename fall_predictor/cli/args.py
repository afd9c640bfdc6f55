"""Arguments of the ``fall-predictor`` command line: the types (each parses one option's text
or raises ``argparse.ArgumentTypeError`` naming the bad value), the bring-up options, and the
output helpers (``emit``, ``fail``) every ``cli_*`` module shares."""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path


def emit(args, payload: dict, lines: list[str]) -> None:
    """Print ``payload`` as one JSON object with ``--json``, else the human-readable ``lines``."""
    text = json.dumps(payload, sort_keys=True) if getattr(args, 'json', False) else '\n'.join(lines)
    try:
        print(text, flush=True)
    except BrokenPipeError:
        # The reader (e.g. `| head`) went away: not an error of ours, and no traceback.
        sys.stdout = None


def fail(command: str, error: Exception | str) -> int:
    """A dataset, model file or setting that cannot be used: one clear line, exit code 2 (with
    ``--debug``, the error itself, traceback and all)."""
    from fall_predictor.errors import debug, one_line
    if debug() and isinstance(error, BaseException):
        raise error
    print(f'fall-predictor {command}: error: {one_line(error)}', file=sys.stderr)
    return 2


def add_robot_argument(parser: argparse.ArgumentParser) -> None:
    """``--robot NAME|PATH``: the robot profile (profiles/), checked when parsed."""
    from fall_predictor.profiles.profile import DEFAULT_ROBOT, ProfileError, available_profiles, load_profile

    def robot(text: str) -> str:
        try:
            load_profile(text)
        except ProfileError as error:
            raise argparse.ArgumentTypeError(str(error)) from error
        return text

    parser.add_argument('--robot', type=robot, default=DEFAULT_ROBOT, metavar='NAME|PATH',
                        help=f'robot profile: {", ".join(available_profiles())} or the path to a '
                             f'profile file (default {DEFAULT_ROBOT})')


def add_controller_arguments(parser: argparse.ArgumentParser) -> None:
    """``--controller NAME`` and ``--simulator {pybullet,mujoco}``: who walks the robot, and in
    which simulator (defaults: the robot profile's; checked against it by :func:`controller_of`)."""
    from fall_predictor.profiles.profile import C_BAL
    from fall_predictor.sim.world import SIMULATORS
    parser.add_argument('--controller', default=None, metavar='NAME',
                        help=f'the walking controller: {C_BAL!r} (the package\'s balance controller) '
                             'or a learned policy the robot profile names (default: the profile\'s)')
    parser.add_argument('--simulator', choices=SIMULATORS, default=None,
                        help='the simulator (default: the robot profile\'s)')


def controller_of(args) -> tuple[str, str]:
    """(controller, simulator) of ``args`` (--robot, --controller, --simulator), the profile's
    where not given; ProfileError for a controller the robot does not have."""
    from fall_predictor.profiles.profile import load_profile
    profile = load_profile(args.robot)
    controller = getattr(args, 'controller', None) or profile.default_controller
    profile.controller_profile(controller)
    return controller, getattr(args, 'simulator', None) or profile.simulator


def checked_profile(robot, controller: str | None = None):
    """The profile of ``robot`` once the static part of ``fall-predictor check`` passes for
    ``controller`` (sim/checks.py); else ``StaticCheckFailed`` (a TeamFileError: one line naming
    the file, the field and what to do)."""
    from fall_predictor.sim.checks import require_static_checks
    return require_static_checks(robot, controller)


def unpushed_fall_causes(profile, controller: str) -> str:
    """Where to look when ``profile``'s robot falls under ``controller`` with no push: the likely
    causes in its files (``fall-predictor check`` runs it and says more)."""
    policy = profile.controller_profile(controller)
    if policy is None:
        return f'servo_gains or the controller section of {profile.source}'
    return ('the joint order of joint_names, default_angles in degrees, the sign of action_scale, '
            f'the gait clock (gait_period_s), in {policy.policy_path}')


def add_scheduler_argument(parser: argparse.ArgumentParser, what: str) -> None:
    """``--scheduler ADDRESS``: run ``what`` on a Dask cluster instead of local processes."""
    parser.add_argument('--scheduler', default=None, metavar='ADDRESS',
                        help=f'run {what} on the Dask cluster whose scheduler is at ADDRESS '
                             '(e.g. tcp://10.0.0.5:8786; start it with `dask scheduler` and '
                             '`dask worker ADDRESS --nthreads 1` on each machine); --jobs then '
                             'applies only to the local work. Results equal a local run\'s')


def finite(kind):
    def parse(text: str):
        value = kind(text)
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f'{text!r} is not a finite number')
        return value
    return parse


def positive(text: str) -> float:
    value = finite(float)(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f'{text!r} must be > 0')
    return value


def positive_int(text: str) -> int:
    value = int(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f'{text!r} must be a positive integer')
    return value


def nonnegative(text: str) -> float:
    value = finite(float)(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f'{text!r} must be >= 0')
    return value


def force_range(text: str) -> tuple[float, float]:
    """``LOW,HIGH``: a push force range [N] (two finite numbers, 0 <= LOW <= HIGH)."""
    from fall_predictor.sim.pushes import checked_force_range
    try:
        low, high = (float(part) for part in text.split(','))
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r}: expected LOW,HIGH, two numbers in newtons '
                                         '(e.g. 150,300)') from None
    try:
        return checked_force_range(low, high)
    except ValueError as error:
        raise argparse.ArgumentTypeError(f'{text!r}: {error}') from None


def at_least_two(text: str) -> int:
    value = int(text)
    if value < 2:
        raise argparse.ArgumentTypeError(f'{text!r} must be an integer >= 2')
    return value


def list_of(element):
    """Parser of a comma-separated list whose elements ``element`` parses."""
    def parse(text: str) -> tuple:
        try:
            values = tuple(element(part) for part in text.split(',') if part.strip())
        except ValueError as error:
            raise argparse.ArgumentTypeError(f'{text!r}: {error}') from error
        if not values:
            raise argparse.ArgumentTypeError(f'{text!r}: expected a comma-separated list')
        return values
    return parse


def learner_param(text: str) -> tuple:
    """``KEY=VALUE``; VALUE is read as JSON (``8``, ``0.5``, ``null``) or else kept as a string."""
    key, separator, raw = text.partition('=')
    if not separator or not key.strip():
        raise argparse.ArgumentTypeError(f'{text!r}: expected KEY=VALUE')
    try:
        value = json.loads(raw)
    except json.JSONDecodeError:
        value = raw
    return key.strip(), value


def non_negative_int(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f'{text!r} must be >= 0')
    return value


def domain_id(text: str) -> int:
    value = int(text)
    if not 0 <= value <= 232:
        raise argparse.ArgumentTypeError(f'{text!r}: ROS domain ids go from 0 to 232')
    return value


def add_bringup_arguments(parser: argparse.ArgumentParser) -> None:
    """The bring-up options (no ROS import: ``--help`` works without ROS)."""
    parser.add_argument('--pushes', type=non_negative_int, default=1,
                        help='number of pushes, each on a fresh world (default 1)')
    parser.add_argument('--seed', type=int, default=0,
                        help='push i is that of dataset trajectory i with this seed')
    parser.add_argument('--json', action='store_true', help='print one JSON line per push')
    parser.add_argument('--domain-id', type=domain_id, default=None,
                        help='ROS_DOMAIN_ID of the nodes (default: derived from the pid)')
    parser.add_argument('--real-time-factor', type=nonnegative, default=None,
                        help='simulated s per wall s; 0 = as fast as possible (default for '
                             'C_bal); a learned policy runs at 1 by default (its simulator '
                             'outpaces the monitor, which would skip samples)')
    add_robot_argument(parser)
    add_controller_arguments(parser)
    parser.add_argument('--model', type=Path, default=None,
                        help='model file (default: the shipped model of the robot under its '
                             'controller, e.g. models/default_model.json)')
    parser.add_argument('--params-file', type=Path, default=None,
                        help='ROS params file (default: config/fall_predictor.yaml)')
    parser.add_argument('--record', type=Path, default=None, metavar='DIR',
                        help='also run the recorder: one bag per push in DIR')
    parser.add_argument('--horizon', type=nonnegative, default=3.0,
                        help='simulated s watched after a push ends if no fall (default 3)')
    parser.add_argument('--log-dir', type=Path, default=None,
                        help='node logs (default: a new temporary directory)')
    parser.add_argument('--no-fall-trigger', dest='fall_trigger', action='store_false',
                        help='monitor only: the walking controller stays in charge (record training '
                             'data this way)')
    parser.add_argument('--true-state', dest='sensors', action='store_false',
                        help='feed the monitor the simulator\'s exact state instead of the default: the '
                             'simulator publishes robot sensor topics and state_estimator_node makes the '
                             'measurement (exact state then on /fall_predictor/ground_truth); C_bal '
                             'only (a learned policy walks on the sensor topics)')
    parser.add_argument('--sensor-timing', choices=('simulator', 'robot'), default='simulator',
                        help='how the simulated robot publishes its sensors: every stream at 1 kHz with '
                             'one stamp per step, or as a robot\'s drivers (joint states at 500 Hz split '
                             'into legs and upper body, IMU and foot wrenches 0.3 / 0.4 ms after them)')


def add_learner_arguments(p: argparse.ArgumentParser) -> None:
    from fall_predictor.learning.training import DEFAULT_SAMPLE_STRIDE, LEARNER_CLASSES
    p.add_argument('--learner', choices=sorted(LEARNER_CLASSES), default='tree',
                   help='tree: CART tree rewritten as a list; covering: RIPPER-like sequential '
                        'covering (default tree)')
    p.add_argument('--param', type=learner_param, action='append', default=[], metavar='KEY=VALUE',
                   help='learner hyper-parameter, repeatable (e.g. --param max_depth=10); VALUE is JSON')
    p.add_argument('--stride', type=positive_int, default=DEFAULT_SAMPLE_STRIDE,
                   help=f'train on every K-th 1 kHz sample, weights x K (default {DEFAULT_SAMPLE_STRIDE})')


def add_state_argument(p: argparse.ArgumentParser) -> None:
    """``--state``: features from the estimated (default) or the true state (data/dataset.py)."""
    p.add_argument('--state', choices=('estimated', 'true'), default='estimated',
                   help='features from the state estimated from the sensor topics (default; a dataset '
                        'recorded without them falls back to the true state, with a note) or from '
                        'the simulator\'s true state')


def resolved_state(args: argparse.Namespace) -> str:
    """The state ``args.data`` gives features from for ``args.state``; a note on stderr when it
    differs (a dataset without sensor topics). Raises DatasetError for a non-dataset."""
    from fall_predictor.data.dataset import resolve_state

    state, note = resolve_state(args.data, args.state)
    if note:
        print(f'note: {note}', file=sys.stderr)
    return state
