"""The state estimator against the simulator's ground truth, and on bad input."""
from dataclasses import replace

import numpy as np
import pinocchio as pin
import pybullet as pb
import pytest

from fall_predictor.monitor.contact_modes import classify_contact_mode
from fall_predictor.monitor.estimator import EstimatorConfig, StateEstimator
from fall_predictor.monitor.robot_description import DescriptionError, RobotDescription
from fall_predictor.monitor.records import PushSpec
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.sim.sensors import SensorParams, apply_sensors
from fall_predictor.sim.pybullet_world import PybulletWorld
from fall_predictor.sim.trajectory import run_trajectory


@pytest.fixture(scope='module')
def run():
    return run_trajectory(PushSpec(60.0, 0.0, 0.1, 0.8), 1.3, record_sensors=True)


@pytest.fixture(scope='module')
def readings(run):
    return apply_sensors(run.sensor_truths, SensorParams(), seed=7)


def asimo_estimator(urdf: str = '', config: EstimatorConfig = EstimatorConfig()) -> StateEstimator:
    return StateEstimator(RobotDescription(urdf or rm.URDF_PATH.read_text(), rm.PROFILE.sensor_layout().soles), config,
                          imu_frame=rm.PROFILE.imu_frame)


def _errors(est, truth, name):
    e = np.array([np.linalg.norm(getattr(a, name) - getattr(b, name)) for a, b in zip(est, truth) if a is not None])
    return e[np.isfinite(e)]


def test_pinocchio_com_equals_the_simulators_urdf_com():
    # An independent check of the URDF model: Pinocchio on the description's URDF at the
    # simulator's exact base pose and joint angles gives PyBullet's mass-weighted link CoM.
    model = pin.buildModelFromXML(rm.URDF_PATH.read_text(), pin.JointModelFreeFlyer())
    data = model.createData()
    with PybulletWorld() as sim:
        q0 = np.linspace(-0.3, 0.3, 26)
        m = sim.reset(q0, [0.1, 0.2, 1.0], torso_yaw_rad=0.4)
        pos, orn = pb.getBasePositionAndOrientation(sim.robot, physicsClientId=sim.client)
        rot = np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3)
        q = np.zeros(model.nq)
        q[0:3] = np.asarray(pos) - rot @ np.asarray(rm.TORSO.com_xyz)   # torso origin, not its CoM
        q[3:7] = orn
        for i, name in enumerate(rm.JOINT_NAMES):
            q[model.joints[model.getJointId(name)].idx_q] = sim.joint_states()[0][i]
        assert pin.centerOfMass(model, data, q) == pytest.approx(m.com, abs=1e-6)
        assert sum(i.mass for i in model.inertias) == pytest.approx(sim.total_mass)


def test_estimates_meet_the_aims_against_ground_truth(run, readings):
    est = asimo_estimator().run(readings)
    truth = run.measurements
    assert sum(m is None for m in est) <= 5        # only until a sole anchors the base
    com, lin = _errors(est, truth, 'com'), _errors(est, truth, 'lin_mom')
    assert np.percentile(com, 99) <= 0.010
    assert np.median(lin) <= 0.3 and np.percentile(lin, 99) <= 1.5
    assert np.median(_errors(est, truth, 'ang_mom')) <= 0.2
    assert np.median(_errors(est, truth, 'cop')) <= 0.01
    agree = [classify_contact_mode(a) == classify_contact_mode(b) for a, b in zip(est, truth) if a is not None]
    assert np.mean(agree) >= 0.97


def test_batch_equals_stream(readings):
    batch = asimo_estimator().run(readings[:400])
    live = asimo_estimator()
    for r, b in zip(readings[:400], batch):
        m = live.update(r)
        assert (m is None) == (b is None)
        if m is not None:
            assert np.array_equal(m.com, b.com) and np.array_equal(m.lin_mom, b.lin_mom)
            assert np.array_equal(m.left_contacts, b.left_contacts)


def _sample(r, **changes):
    from dataclasses import replace
    return replace(r, **changes)


def test_bad_input_is_rejected_or_degrades_never_crashes(readings):
    est = asimo_estimator()
    est.run(readings[:100])
    q = readings[100].q.copy()
    q[3] = np.nan
    assert est.update(_sample(readings[100], q=q)) is None and 'non-finite' in est.last_issue
    assert est.update(_sample(readings[99])) is None and 'not after' in est.last_issue   # out of order
    # A foot without a wrench has no contact (the sensor sync never passes None for a foot that
    # has a sensor: it refuses the sample instead).
    m = est.update(_sample(readings[100], left_wrench=None))
    assert m is not None and len(m.left_contacts) == 0 and len(m.right_contacts) > 0
    m = est.update(_sample(readings[101], t=readings[101].t + 1.0))    # stale: a 1 s gap
    assert m is not None and 're-anchored' in est.last_issue
    renamed = ('nope',) + tuple(readings[102].joint_names[1:])
    assert est.update(_sample(readings[102], t=readings[102].t + 1.0, joint_names=renamed)) is None
    assert "joints ['l_hip_yaw'] of the robot description are missing" in est.last_issue
    assert est.update(_sample(readings[102], t=readings[102].t + 1.0, imu_frame='imu_link')) is None
    assert "IMU frame 'imu_link' is not a frame of the robot description" in est.last_issue
    # A wrench frame the description lacks is refused each time a sample names it.
    for k in (103, 104):
        sample = _sample(readings[k], t=readings[k].t + 1.0, wrench_frames=('l_sole', 'l_ankle_imu'))
        assert est.update(sample) is None
        assert "right foot force sensor frame 'l_ankle_imu' is not a frame" in est.last_issue


@pytest.mark.parametrize('axis', ['x', 'y'])
def test_a_tilt_error_in_the_first_sample_does_not_shift_the_world_frame(run, readings, axis):
    # The world frame is put on the soles at the first sample, before the attitude filter has
    # averaged any IMU noise. A 1 deg error there (a MEMS attitude output's accuracy) makes one
    # edge of each flat sole look lower than the other; the frame must still go on the soles'
    # centres, not on those edges (half a sole, 4-11 cm, away).
    from scipy.spatial.transform import Rotation
    truth = {round(m.t * 1000): m for m in run.measurements}
    first = readings[100]
    tilted = (Rotation.from_euler(axis, 1.0, degrees=True) * Rotation.from_quat(first.imu_quat_xyzw)).as_quat()
    est = asimo_estimator()
    out = est.run([_sample(first, imu_quat_xyzw=tilted)] + [_sample(r) for r in readings[101:300]])
    errors = [np.linalg.norm((m.com - truth[round(m.t * 1000)].com)[:2]) for m in out if m is not None]
    assert len(errors) == 200 and errors[0] < 0.01 and max(errors[-50:]) < 0.01


def test_sole_frames_missing_from_the_urdf_come_from_the_profile():
    """The profile puts each sole frame on its foot link: where the full URDF has it."""
    soles = rm.PROFILE.sensor_layout().soles
    with_frames = RobotDescription(rm.urdf_xml(), soles)
    added = RobotDescription(rm.urdf_xml(sole_frames=False), soles)
    q = with_frames.configuration(np.linspace(-0.3, 0.3, len(with_frames.joint_names)))
    for d in (with_frames, added):
        pin.framesForwardKinematics(d.model, d.data, q)
    for side in ('l', 'r'):
        a = with_frames.data.oMf[with_frames.sole_ids[side]]
        b = added.data.oMf[added.sole_ids[side]]
        assert np.allclose(a.translation, b.translation, atol=1e-12)
        assert np.allclose(a.rotation, b.rotation, atol=1e-12)
    # Without the frame in the URDF and without a link to put it on, the estimator cannot work.
    bare = {side: replace(sole, link=None) for side, sole in soles.items()}
    with pytest.raises(DescriptionError, match='needs both sole frames'):
        RobotDescription(rm.urdf_xml(sole_frames=False), bare)


def test_a_malformed_urdf_is_a_clear_error():
    with pytest.raises(DescriptionError, match='cannot build'):
        asimo_estimator('<robot name="x"><link')
    assert EstimatorConfig().contact_force_n > 0


# -- frames from the robot description --------------------------------------------------------

#: An IMU mounted on the torso away from its origin, turned (rpy [rad], xyz [m] in the torso frame).
IMU_RPY, IMU_XYZ = (0.3, -0.2, 1.0), (0.05, 0.02, 0.10)


def _with_imu_link(urdf: str) -> str:
    link = ('<link name="imu_link"/><joint name="imu_joint" type="fixed"><parent link="torso"/>'
            '<child link="imu_link"/><origin xyz="%g %g %g" rpy="%g %g %g"/></joint></robot>'
            % (*IMU_XYZ, *IMU_RPY))
    return urdf.replace('</robot>', link)


def _mounted_imu_truths(truths):
    """The truths of an IMU mounted at IMU_XYZ / IMU_RPY on the torso instead of at its origin."""
    from dataclasses import replace

    from scipy.spatial.transform import Rotation
    mount = Rotation.from_euler('xyz', IMU_RPY)
    out = []
    for truth in truths:
        torso = Rotation.from_quat(truth.imu_quat_xyzw)
        omega_world = torso.apply(truth.gyro_rad_s)
        lever = torso.apply(IMU_XYZ)
        out.append(replace(truth, imu_quat_xyzw=(torso * mount).as_quat(),
                           gyro_rad_s=mount.inv().apply(truth.gyro_rad_s),
                           imu_velocity_world=truth.imu_velocity_world + np.cross(omega_world, lever)))
    return out


def test_an_imu_on_another_link_named_by_its_frame_tracks_as_well(run):
    """The IMU's frame (its messages' frame_id) is resolved in the robot description: mounted
    10 cm off the torso origin and turned by 1 rad, the estimate meets the same aims."""
    from dataclasses import replace
    samples = [replace(s, imu_frame='imu_link')
               for s in apply_sensors(_mounted_imu_truths(run.sensor_truths), SensorParams(), seed=7)]
    est = asimo_estimator(_with_imu_link(rm.URDF_PATH.read_text())).run(samples)
    truth = run.measurements
    assert sum(m is None for m in est) <= 5
    assert np.percentile(_errors(est, truth, 'com'), 99) <= 0.010
    lin = _errors(est, truth, 'lin_mom')
    assert np.median(lin) <= 0.3 and np.percentile(lin, 99) <= 1.5


def test_foot_wrenches_in_another_frame_are_carried_to_the_soles(readings):
    """Wrenches reported in the ankle frame (the foot link, 7 cm above the sole) give exactly the
    sole-frame estimates: the frame of each WrenchStamped is resolved in the description."""
    from dataclasses import replace
    r_sole = np.asarray(rm.SOLE_ORIGIN_IN_FOOT_M)          # sole origin in the foot (ankle) frame

    def at_ankle(w):
        f, tau = w[:3], w[3:]
        return np.concatenate([f, tau + np.cross(r_sole, f)])    # same axes, moment about the ankle
    ankle = [replace(s, left_wrench=at_ankle(s.left_wrench), right_wrench=at_ankle(s.right_wrench),
                     wrench_frames=('l_foot', 'r_foot')) for s in readings[:400]]
    direct = asimo_estimator().run(readings[:400])
    carried = asimo_estimator().run(ankle)
    for a, b in zip(direct, carried):
        assert (a is None) == (b is None)
        if a is not None:
            np.testing.assert_allclose(a.cop, b.cop, atol=1e-9)
            np.testing.assert_allclose(a.com, b.com, atol=1e-9)


def test_continuous_joints_and_joints_in_any_order(readings):
    """A continuous joint (cos/sin in Pinocchio) and a sample listing the joints in reverse give
    the estimates of the revolute, URDF-ordered case."""
    from dataclasses import replace
    urdf = rm.URDF_PATH.read_text().replace('<joint name="head_pan" type="revolute">',
                                            '<joint name="head_pan" type="continuous">')
    assert 'type="continuous"' in urdf
    order = np.arange(len(rm.JOINT_NAMES))[::-1]
    reversed_samples = [replace(s, joint_names=tuple(np.array(s.joint_names)[order]),
                                q=s.q[order], dq=s.dq[order]) for s in readings[:300]]
    direct = asimo_estimator().run(readings[:300])
    other = asimo_estimator(urdf).run(reversed_samples)
    # Two message layouts alternating sample by sample: each sample read in its own order.
    mixed = asimo_estimator().run([r if k % 2 else s for k, (s, r)
                                   in enumerate(zip(readings[:300], reversed_samples))])
    for a, b in zip(direct, mixed):
        assert (a is None) == (b is None)
        if a is not None:
            np.testing.assert_allclose(a.lin_mom, b.lin_mom, atol=1e-9)
    for a, b in zip(direct, other):
        assert (a is None) == (b is None)
        if a is not None:
            np.testing.assert_allclose(a.com, b.com, atol=1e-9)
            np.testing.assert_allclose(a.lin_mom, b.lin_mom, atol=1e-9)


def test_a_fall_dead_reckoned_below_the_ground_stops_there_and_stays_estimated(readings):
    """From 0.5 s on no sole is loaded and the accelerometer reads free fall: integrated alone,
    the CoM would sink g t^2 / 2 (4.9 m in 1 s) through the ground; the ground stops it, and every
    estimate stays one a humanoid can be in (a fallen one), none refused."""
    from fall_predictor.monitor.plausibility import check_measurement
    falling = [replace(s, left_wrench=np.zeros(6), right_wrench=np.zeros(6), accel_m_s2=np.zeros(3))
               if s.t >= 0.5 else s for s in readings]
    est = asimo_estimator().run(falling)
    after = [m for s, m in zip(falling, est) if s.t >= 0.5]
    assert len(after) > 500 and all(m is not None for m in after)
    for m in after:
        check_measurement(m)
    heights = np.array([m.com[2] for m in after])
    assert heights.min() >= 0.0 and heights[-1] < 0.001       # stopped on the ground, not below
    assert np.all(np.isnan([m.cop[0] for m in after]))         # no sole loaded: no CoP


def test_a_sole_cop_computed_off_the_sole_is_kept_on_it(readings):
    """A light load with a large torque (a leg's effort-derived wrench as it slips or falls): its
    CoP computed -ty / fz lies 2 m ahead of the sole; the CoP of unilateral contact forces lies
    under the sole, and the estimate keeps it there (not a CoP 2 m from the CoM)."""
    sole = rm.PROFILE.feet['l']
    half_diagonal = np.hypot(sole.sole_length_m / 2, sole.sole_width_m / 2)
    k = next(i for i, s in enumerate(readings) if s.t >= 0.4)
    light = [replace(s, left_wrench=np.array([0.0, 0.0, 15.0, 0.0, -30.0, 0.0]),
                     right_wrench=np.zeros(6), wrench_frames=('', '')) if i >= k else s
             for i, s in enumerate(readings[:k + 50])]
    est = asimo_estimator().run(light)
    for m in est[k:]:
        assert m is not None
        off = np.hypot(*(m.cop[:2] - m.left_foot[:2]))
        assert off <= half_diagonal + 1e-9, off
    # Where the torque puts it: the sole's front edge (x ahead in the sole frame).
    m = est[-1]
    heading = m.left_foot[2]
    ahead = (m.cop[:2] - m.left_foot[:2]) @ np.array([np.cos(heading), np.sin(heading)])
    assert ahead == pytest.approx(sole.sole_length_m / 2, abs=0.02)
