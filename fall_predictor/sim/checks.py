"""``fall-predictor check``'s checks that need the simulator (method §13): the MJCF against the
URDF, and the robot standing and walking under each of its controllers; and all of them together.

Static (:func:`static_checks`, a second or so): the profile and URDF (profiles/checks.py), the
MJCF (it loads; its joints are the URDF's; its total mass within 1 % of the URDF's; its CoM at the
default posture within 2 cm of the URDF's; its joint ranges ordered; feet, IMU, base, ground), each learned controller's
deploy config and network (robot/checks.py), and C_bal's servo table when C_bal drives the robot.
``generate``, ``calibrate``, ``simulate``, ``render`` and the nodes run it first
(:func:`require_static_checks`) and refuse a robot that fails it.

Dynamic (:func:`dynamic_checks`, seconds per controller): without any push, a learned policy
stands 5 s at a zero command and walks 5 s forward and 5 s turning (inside its profile's command
range); C_bal walks its gait 5 s. Each run must not fall, and a walk must go roughly where it is
commanded (distance and heading after its first second); a failure names the likely causes.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from typing import Any, Optional, Sequence

import numpy as np

from fall_predictor.profiles.checks import (Check, failed, nearest, passed, profile_checks,
                                            urdf_checks)
from fall_predictor.profiles.profile import C_BAL, ProfileError, RobotProfile

#: The MJCF's CoM may be this far from the URDF's at the default posture [m]: the monitor
#: estimates from the URDF what the simulator moves by the MJCF; 2 cm is about 3 % of a
#: humanoid's CoM height (the shipped G1 pair agrees to a micrometre).
COM_TOLERANCE_M = 0.02
#: The MJCF's mass may be this far from the URDF's [fraction].
MASS_TOLERANCE = 0.01
#: Each dynamic run [s], and the part of it a walk's distance and heading are measured over.
RUN_S = 5.0
MEASURE_FROM_S = 1.0
#: A walk's distance along the command must be within these fractions of commanded x time, and
#: its sideways drift within this fraction of it (+ 0.1 m). Unitree's G1 policy: 92 % and 3 %;
#: with its gait clock at half its period: 132 % and 35 % (it still walks, the wrong gait).
WALK_DISTANCE_FRACTION = (0.5, 1.3)
WALK_LATERAL_FRACTION = 0.2
#: Heading change allowed when not turning [deg]; a turn's change must be within these fractions.
STRAIGHT_HEADING_DEG = 20.0
TURN_FRACTION = (0.5, 1.5)
#: How far a standing robot may drift [m] (the G1 policy: 6 cm in 4 s).
STAND_DRIFT_M = 0.25

POLICY_CAUSES = ('the left/right (or any) joint order of joint_names', 'default_angles in degrees',
                 'the sign of action_scale', 'the gait clock (gait_period_s; sin/cos order)',
                 'kps/kds', 'the IMU frame (the policy reads the base\'s)')
C_BAL_CAUSES = ('servo_gains', 'the URDF\'s masses and limits', 'the controller section (gait)')


#: Checks whose failure leaves nothing further to check (the URDF unread, its frames unknown).
BLOCKING = ('profile loads', 'URDF parses', 'URDF model', 'profile frames')


class StaticCheckFailed(ProfileError):
    """A robot's files fail ``fall-predictor check --static``: the first failure, in one line."""


# -- static -------------------------------------------------------------------------------------

def static_checks(robot: Any, controller: Optional[str] = None,
                  every: bool = True) -> tuple[list[Check], Optional[RobotProfile]]:
    """Every static check of ``robot`` (a profile name or path) for ``controller`` (None: each
    controller the robot has: its learned ones, and C_bal when it is the default or, with
    ``every``, the profile has its servo table), and the profile (None when it does not load)."""
    from fall_predictor.robot.checks import policy_checks

    checks, profile = profile_checks(robot)
    if profile is None:
        return checks, None
    names = controllers_to_check(profile, controller, every)
    unknown = [n for n in names if n != C_BAL and n not in profile.controllers]
    if unknown:
        checks.append(failed('controller', f'robot {profile.name!r} has no controller {unknown[0]!r}'
                             + nearest(unknown[0], profile.controller_names),
                             f'choose one of {", ".join(profile.controller_names)}', profile.source,
                             'controllers'))
        return checks, profile
    posture = standing_posture(profile, names)
    checks += urdf_checks(profile, posture)
    if any(not c.ok for c in checks if c.name in BLOCKING):
        return checks, profile              # nothing further can be read
    limits = urdf_joint_limits(profile)
    if profile.mjcf_path is not None:
        checks += mjcf_checks(profile, posture, limits)
    else:                                   # the simulator loads the URDF, meshes and all
        checks.append(urdf_mesh_check(profile))
    for name in names:
        if name == C_BAL:
            checks.append(c_bal_check(profile))
        else:
            checks += policy_checks(profile, profile.controllers[name], limits)
            order = actuator_order_check(profile, name)
            if order is not None:
                checks.append(order)
    return checks, profile


def controllers_to_check(profile: RobotProfile, controller: Optional[str],
                         every: bool = True) -> list[str]:
    """``[controller]``, or (None) the learned controllers and C_bal when it is the default or,
    with ``every``, whenever the profile has its servo table."""
    if controller is not None:
        return [controller]
    names = list(profile.controllers)
    if profile.default_controller == C_BAL or (every and profile.servo_gains):
        names.insert(0, C_BAL)
    return names


def standing_posture(profile: RobotProfile, controllers: Sequence[str]) -> dict[str, float]:
    """The joint angles the robot stands at: the first learned controller's default angles (those
    it starts from), else the profile's posture (legs straight)."""
    from fall_predictor.robot.policy_config import PolicyConfigError, read_policy_config

    posture = dict(profile.posture)
    for name in controllers:
        if name != C_BAL and name in profile.controllers:
            try:
                config = read_policy_config(profile.controllers[name].policy_path)
            except PolicyConfigError:
                break                        # its own check says why
            if all(abs(a) <= math.pi for a in config.default_angles_rad):
                posture.update(zip(config.joint_names, config.default_angles_rad))
            break
    return posture


def urdf_joint_limits(profile: RobotProfile) -> dict[str, tuple[float, float]]:
    """The URDF's movable joints: name -> (lower, upper) [rad or m] (continuous: +-inf)."""
    limits = {}
    for joint in ET.parse(profile.urdf_path).getroot().iter('joint'):
        kind = joint.get('type')
        if kind not in ('revolute', 'continuous', 'prismatic'):
            continue
        limit = joint.find('limit')
        try:
            bounds = (float(limit.get('lower', 0)), float(limit.get('upper', 0)))
        except (AttributeError, ValueError):            # none, or not numbers (a failed check)
            bounds = (-math.inf, math.inf)
        limits[joint.get('name')] = (-math.inf, math.inf) if kind == 'continuous' else bounds
    return limits


def mjcf_actuator_joints(path) -> list[str]:
    """The joints of the MJCF's actuators, in their order (the order of ``ctrl``), the files it
    includes read too."""
    from pathlib import Path
    files, joints = [Path(path)], []
    for file in files:
        try:
            root = ET.parse(file).getroot()
        except (ET.ParseError, OSError):
            continue
        for element in root.iter():
            if element.tag == 'include' and element.get('file'):
                files.append(file.parent / element.get('file'))
        for actuators in root.iter('actuator'):
            joints += [a.get('joint') for a in actuators if a.get('joint')]
    return joints


def actuator_order_check(profile: RobotProfile, name: str) -> Optional[Check]:
    """A warning when a policy's joint_names list the MJCF's actuated joints in another order:
    teams' sim2sim loops (Unitree's deploy_mujoco) send action k to actuator k, so a policy
    trained that way lists them in the actuator order. (Joints are matched by name here; the
    order is the policy's, and may be intended.)"""
    from fall_predictor.robot.policy_config import PolicyConfigError, read_policy_config

    if profile.mjcf_path is None:
        return None
    actuated = mjcf_actuator_joints(profile.mjcf_path)
    try:
        config = read_policy_config(profile.controllers[name].policy_path)
    except PolicyConfigError:
        return None
    names = list(config.joint_names)
    if sorted(actuated) != sorted(names) or actuated == names:
        return None
    first = next(k for k, (a, b) in enumerate(zip(actuated, names)) if a != b)
    return Check(f'{name}: joint order', False, f'joint_names lists {names[first]!r} as action '
                 f'{first}, the MJCF\'s actuator {first} is {actuated[first]!r}',
                 'list joint_names in the order the policy was trained with (the actuator order, '
                 'for a policy trained in that MJCF)', str(config.source), 'joint_names',
                 warning=True)


def urdf_mesh_check(profile: RobotProfile) -> Check:
    """Every mesh file the simulator's URDF names is there (PyBullet refuses the URDF otherwise)."""
    from fall_predictor.sim.urdf_loading import MissingPackageError, missing_mesh_files

    path = profile.sim_urdf_path
    try:
        missing = missing_mesh_files(path)
    except MissingPackageError as error:
        return failed('URDF meshes', str(error), 'install it', path, 'mesh')
    if missing:
        return failed('URDF meshes', f'mesh file {missing[0]!r} not found'
                      + (f' (and {len(missing) - 1} more)' if len(missing) > 1 else ''),
                      'put the meshes where the URDF names them (relative to its folder)', path,
                      'mesh')
    return passed('URDF meshes', f'{path.name}: every mesh file found')


def c_bal_check(profile: RobotProfile) -> Check:
    """C_bal drives every joint through the profile's servo table: an entry for each."""
    from fall_predictor.profiles.profile import ProfileError
    missing = []
    for joint in profile.joint_names:
        try:
            profile.gains_for(joint)
        except ProfileError:
            missing.append(joint)
    if missing:
        return failed('c_bal: servo gains', f'no servo_gains entry for {", ".join(missing[:3])}'
                      + (' ...' if len(missing) > 3 else ''), 'give C_bal a servo table (copy '
                      'g1/profile.yaml\'s servo_gains), or run the robot under its learned policy '
                      '(--controller)', profile.source, 'servo_gains')
    return passed('c_bal: servo gains', f'an entry for each of the {len(profile.joint_names)} joints')


def mjcf_checks(profile: RobotProfile, posture: dict[str, float],
                urdf_limits: dict[str, tuple[float, float]]) -> list[Check]:
    """The MJCF loads and agrees with the URDF (module docstring)."""
    from fall_predictor.sim.mujoco_model import load_model
    import mujoco

    path = mjcf_files(profile.mjcf_path)
    try:
        model = load_model(profile)
    except (ValueError, OSError) as error:
        text = getattr(error, 'problem', None) or str(error)
        return [failed('MJCF loads', _missing_asset(profile.mjcf_path, text) or text,
                       'fix the MJCF (or the file it names: meshes, includes)', path, 'mjcf')]
    checks = [passed('MJCF loads', f'{profile.mjcf_path.name}: {model.nbody - 1} bodies, '
                     f'{model.njnt} joints')]
    hinge = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    joints = {model.joint(j).name: j for j in range(model.njnt) if int(model.jnt_type[j]) in hinge}
    only_mjcf = sorted(set(joints) - set(urdf_limits))
    only_urdf = sorted(set(urdf_limits) - set(joints))
    if only_urdf:                           # the world drives every joint of the URDF
        checks.append(failed('MJCF joints', f'joints of the URDF the MJCF lacks: {only_urdf}'
                             + nearest(only_urdf[0], joints) + (f'; only in the MJCF: {only_mjcf}'
                                                                 if only_mjcf else ''),
                             'give the MJCF the URDF\'s joint names', path, only_urdf[0]))
        return checks
    if only_mjcf:                           # passive joints the URDF does not have: said
        checks.append(Check('MJCF joints', False, f'joints only in the MJCF (not driven, not '
                            f'estimated): {only_mjcf}', 'give the URDF the same joints, unless '
                            'they are meant to be passive', path, only_mjcf[0], warning=True))
    # MuJoCo silently leaves a joint whose range is inverted unlimited ('auto' limits).
    inverted = [n for n, j in joints.items() if model.jnt_range[j][0] > model.jnt_range[j][1]
                or (model.jnt_limited[j] and model.jnt_range[j][0] == model.jnt_range[j][1])]
    if inverted:
        checks.append(failed('MJCF joints', f'range not ordered for {", ".join(inverted)}',
                             'write range="lower upper" with lower < upper', path, inverted[0]))
    else:
        checks.append(passed('MJCF joints', f'the URDF\'s {len(joints)} joints, ranges ordered'))
    frames = _mjcf_frames(profile, model, path)
    checks.append(frames)
    if frames.ok:
        checks += _mjcf_mass_and_com(profile, model, joints, posture)
    return checks


def _mjcf_frames(profile: RobotProfile, model, path: str) -> Check:
    """What the MuJoCo world finds in the MJCF: a free base, a ground, each foot link as a body,
    the IMU frame (a body, a site, or fixed in the URDF to a body)."""
    import mujoco

    from fall_predictor.sim.mujoco_model import FloatingBase, fixed_frame_in_body, robot_geoms

    for side, foot in profile.feet.items():
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, foot.foot_link) < 0:
            return failed('MJCF frames', f'foot link {foot.foot_link!r} is not a body of the MJCF',
                          'name the foot\'s body (the MJCF\'s and the URDF\'s link names agree)',
                          profile.source, f'feet.{side}.foot_link')
    try:
        fixed_frame_in_body(model, profile, profile.imu_frame)
    except ValueError as error:
        return failed('MJCF frames', getattr(error, 'problem', str(error)), 'name a body or site '
                      'of the MJCF, or a URDF link fixed to one', profile.source, 'imu_frame')
    try:
        robot_geoms(model, FloatingBase(model, profile.source).body)
    except ValueError as error:
        return failed('MJCF frames', str(error).replace(f'{profile.source}: ', ''),
                      'give the robot a free base and the scene a ground', path, 'worldbody')
    return passed('MJCF frames', 'a free base, a ground, both feet and the IMU found')


def _mjcf_mass_and_com(profile: RobotProfile, model, joints: dict[str, int],
                       posture: dict[str, float]) -> list[Check]:
    import mujoco

    from fall_predictor.profiles.checks import standing_geometry

    description = profile.sensor_layout().description(profile.urdf_xml())
    root = _robot_root(model)
    bodies = [b for b in range(1, model.nbody) if _under(model, b, root)]
    mjcf_mass = float(sum(model.body_mass[b] for b in bodies))
    urdf_mass = description.total_mass_kg
    path = mjcf_files(profile.mjcf_path)
    if abs(mjcf_mass - urdf_mass) > MASS_TOLERANCE * urdf_mass:
        return [failed('MJCF mass', f'the MJCF\'s bodies weigh {mjcf_mass:.3f} kg, the URDF\'s '
                       f'links {urdf_mass:.3f} kg', 'make the two models the same robot (the '
                       '<inertial mass> of each body)', path, 'mass')]
    data = mujoco.MjData(model)
    for name, j in joints.items():
        data.qpos[model.jnt_qposadr[j]] = posture.get(name, 0.0)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    com_mjcf = data.subtree_com[root]
    rotation = data.xmat[root].reshape(3, 3)
    com_mjcf_in_root = rotation.T @ (com_mjcf - data.xpos[root])
    com_urdf, _ = standing_geometry(description, posture)
    gap = float(np.linalg.norm(com_mjcf_in_root - com_urdf))
    checks = [passed('MJCF mass', f'{mjcf_mass:.3f} kg, the URDF\'s {urdf_mass:.3f} kg within '
                     f'{MASS_TOLERANCE:.0%}')]
    if gap > COM_TOLERANCE_M:
        checks.append(failed('MJCF CoM', f'at the default posture the MJCF\'s CoM is '
                             f'{gap * 1000:.0f} mm from the URDF\'s (in the base frame)',
                             'make the two models the same robot (body positions and inertials)',
                             path, 'inertial'))
    else:
        checks.append(passed('MJCF CoM', f'{gap * 1000:.1f} mm from the URDF\'s at the default posture'))
    return checks


def _missing_asset(path, message: str) -> Optional[str]:
    """MuJoCo's "Error opening file" said as the asset missing from the folder the MJCF names
    (MuJoCo's own message names a path without its meshdir when the file is absent)."""
    import re
    from pathlib import Path

    found = re.search(r"Error opening file '([^']+)'", message)
    if found is None:
        return None
    name = Path(found.group(1)).name
    folders = []
    files = [Path(path)]
    for file in files:
        try:
            root = ET.parse(file).getroot()
        except (ET.ParseError, OSError):
            continue
        files += [file.parent / e.get('file') for e in root.iter('include') if e.get('file')]
        folders += [(file.parent / e.get(key)) for e in root.iter('compiler')
                    for key in ('meshdir', 'assetdir') if e.get(key)]
    where = ', '.join(f'{f}/' for f in dict.fromkeys(folders)) or f'{Path(path).parent}/'
    return f'asset {name!r} is not in {where} (MuJoCo looked for {found.group(1)})'


def mjcf_files(path) -> str:
    """The MJCF file and those it includes (a scene including its robot's file): where the
    robot's bodies and joints are."""
    try:
        included = [e.get('file') for e in ET.parse(path).getroot().iter('include') if e.get('file')]
    except (ET.ParseError, OSError):
        included = []
    return f'{path} (and {", ".join(included)}, which it includes)' if included else str(path)


def _robot_root(model) -> int:
    """The robot's root body: the first child of the world with a joint (its floating base)."""
    for body in range(1, model.nbody):
        if model.body_parentid[body] == 0 and model.body_jntnum[body] > 0:
            return body
    return 1


def _under(model, body: int, root: int) -> bool:
    while body > 0:
        if body == root:
            return True
        body = model.body_parentid[body]
    return False


def require_static_checks(robot: Any, controller: Optional[str] = None) -> RobotProfile:
    """The profile of ``robot``, once its static checks pass for ``controller`` (None: its
    learned controllers, and C_bal when it is the default); else :class:`StaticCheckFailed` with
    the first failure in one line (and how many more, and the command that lists them)."""
    checks, profile = static_checks(robot, controller, every=False)
    failures = [c for c in checks if not c.ok and not c.warning]
    if failures or profile is None:
        first = failures[0]
        more = f' ({len(failures) - 1} more)' if len(failures) > 1 else ''
        raise StaticCheckFailed(f'{first.line()}{more} [fall-predictor check --robot {robot} '
                                'lists every check]')
    return profile


# -- dynamic ------------------------------------------------------------------------------------

def dynamic_checks(profile: RobotProfile, controller: str, simulator: Optional[str] = None) -> list[Check]:
    """Runs without a push under ``controller`` (module docstring)."""
    if controller == C_BAL:
        return [_run_check(profile, controller, simulator, None, 'walks its gait')]
    policy = profile.controllers[controller]
    ranges = policy.command
    commands = [((0.0, 0.0, 0.0), 'stands')]
    vx = min(0.5, ranges.vx_m_s[1])
    if vx >= 0.1:
        commands.append(((vx, 0.0, 0.0), f'walks forward at {vx:g} m/s'))
    yaw = min(0.5, ranges.yaw_rate_rad_s[1])
    if yaw >= 0.1:
        commands.append(((0.0, 0.0, yaw), f'turns at {yaw:g} rad/s'))
    return [_run_check(profile, controller, simulator, command, what) for command, what in commands]


def _run_check(profile: RobotProfile, controller: str, simulator: Optional[str],
               command: Optional[tuple[float, float, float]], what: str) -> Check:
    from fall_predictor.robot.control import make_controller
    from fall_predictor.sim.policy_runs import physics_dt_s
    from fall_predictor.sim.trajectory import run_trajectory
    from fall_predictor.sim.world import make_world

    policy = profile.controller_profile(controller)
    world = make_world(profile, simulator, physics_dt_s(policy))
    try:
        walker = make_controller(profile, controller, command, dt_s=world.dt_s,
                                 walk_duration_s=RUN_S + 5.0)
        result = run_trajectory(None, RUN_S, world=world, controller=walker)
    finally:
        world.close()
    name = f'{controller}: {what}'
    causes = C_BAL_CAUSES if policy is None else POLICY_CAUSES
    where = profile.source if policy is None else policy.policy_path
    fix = 'check ' + '; '.join(causes)
    if result.fallen:
        return failed(name, f'fell at {result.t_fallen:.2f} s with no push', fix, where, None)
    found, problems = command_problems(result.measurements, command)
    if problems:
        return failed(name, f'{found}: ' + ', '.join(problems), fix, where, None)
    return passed(name, found + ', never fell')


def command_problems(measurements: Sequence, command: Optional[Sequence[float]],
                     until_s: Optional[float] = None) -> tuple[str, list[str]]:
    """How a walk without a push went from its first second to ``until_s`` (default: its end):
    what it did, and how that differs from ``command`` = (vx, vy, yaw rate), or, None, from a
    gait of its own (C_bal's: forward, straight). Its distance, sideways drift and turn must be
    those of the command within the fractions of this module's constants."""
    window = [m for m in measurements if m.t >= MEASURE_FROM_S - 1e-9
              and (until_s is None or m.t <= until_s + 1e-9)]
    start, end = window[0], window[-1]
    heading0 = start.heading
    d = np.asarray(end.com[:2]) - np.asarray(start.com[:2])
    forward = d[0] * math.cos(heading0) + d[1] * math.sin(heading0)
    lateral = -d[0] * math.sin(heading0) + d[1] * math.cos(heading0)
    turned = math.degrees(float(np.unwrap([m.heading for m in window])[-1] - heading0))
    seconds = end.t - start.t
    # The path's length from the CoM every half second (a step's sway averaged out).
    every = max(1, int(round(0.5 / max(window[1].t - window[0].t, 1e-6)))) if len(window) > 1 else 1
    points = np.array([m.com[:2] for m in window[::every]] + [end.com[:2]])
    path = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
    found = (f'{forward:+.2f} m forward, {lateral:+.2f} m to the left, turned {turned:+.0f} deg '
             f'in {seconds:.1f} s')
    problems: list[str] = []
    if command is None:                                      # a gait of its own
        if abs(turned) > STRAIGHT_HEADING_DEG:
            problems.append('its heading drifts')
        if forward < -0.05:
            problems.append('it walks backwards')
        return found, problems
    vx, vy, yaw = (float(v) for v in command)
    speed = math.hypot(vx, vy)
    turning = abs(yaw) >= 0.05
    low, high = WALK_DISTANCE_FRACTION
    if speed < 0.05 and not turning:                         # standing
        if math.hypot(forward, lateral) > STAND_DRIFT_M:
            problems.append(f'it drifts {math.hypot(forward, lateral):.2f} m at a zero command')
    elif speed >= 0.05 and turning:                          # a curve: its length and its turn
        if not low * speed * seconds <= path <= high * speed * seconds + 0.1:
            problems.append(f'walked {path:.2f} m of the {speed * seconds:.2f} m commanded')
    elif speed >= 0.05:                                      # straight
        along = (forward * vx + lateral * vy) / speed
        across = (-forward * vy + lateral * vx) / speed
        if not low * speed * seconds <= along <= high * speed * seconds:
            problems.append(f'walked {along:.2f} m of the {speed * seconds:.2f} m commanded')
        if abs(across) > WALK_LATERAL_FRACTION * speed * seconds + 0.1:
            problems.append(f'drifted {across:+.2f} m across the commanded direction')
    if not turning and abs(turned) > STRAIGHT_HEADING_DEG:
        problems.append(f'turned {turned:+.0f} deg where no turn was commanded')
    elif turning:
        wanted = math.degrees(yaw * seconds)
        if not TURN_FRACTION[0] <= turned / wanted <= TURN_FRACTION[1]:
            problems.append(f'turned {turned:+.0f} deg of the {wanted:+.0f} deg commanded')
    return found, problems
