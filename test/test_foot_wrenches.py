"""Each sole's wrench as the estimator reads it: a sensor's frame carried to the sole, faulty
readings as no wrench, an unknown frame refused every time it is named."""
import numpy as np
import pinocchio as pin
import pytest

from fall_predictor.monitor.foot_wrenches import FootWrenches, all_finite
from fall_predictor.monitor.robot_description import DescriptionError, RobotDescription
from fall_predictor.monitor.sensor_records import SensorSample
from fall_predictor.profiles import asimo_like_urdf as rm


@pytest.fixture(scope='module')
def robot() -> RobotDescription:
    return RobotDescription(rm.URDF_PATH.read_text(), rm.PROFILE.sensor_layout().soles)


def _sample(robot: RobotDescription, left, right, frames=('', '')) -> SensorSample:
    n = len(robot.joint_names)
    return SensorSample(t=0.0, joint_names=robot.joint_names, q=np.zeros(n), dq=np.zeros(n),
                        imu_quat_xyzw=np.array([0.0, 0.0, 0.0, 1.0]), gyro_rad_s=np.zeros(3),
                        accel_m_s2=np.array([0.0, 0.0, 9.81]), left_wrench=left, right_wrench=right,
                        wrench_frames=frames)


def test_a_wrench_in_the_ankle_frame_is_carried_to_the_sole_as_pinocchio_carries_a_force(robot):
    rng = np.random.default_rng(3)
    q = robot.configuration(rng.uniform(-0.3, 0.3, len(robot.joint_names)))
    pin.framesForwardKinematics(robot.model, robot.data, q)
    reading = np.array([12.0, -30.0, 400.0, 3.0, -7.0, 0.5])
    wrenches = FootWrenches(robot, (), 0.015, 0.003).read(
        _sample(robot, reading, None, ('l_foot', '')), None, q, np.zeros(robot.model.nv), {}, [])
    # Independently: the sensor frame's force expressed in the sole frame by Pinocchio.
    data = robot.data
    ankle = data.oMf[robot.model.getFrameId('l_foot')]
    sole = data.oMf[robot.sole_ids['l']]
    expected = sole.actInv(ankle).act(pin.Force(reading[:3], reading[3:]))
    np.testing.assert_allclose(wrenches['l'], np.concatenate([expected.linear, expected.angular]),
                               atol=1e-9)
    assert wrenches['r'] is None
    # The sole frame itself, named or left empty, passes the reading through unchanged.
    for frames in (('l_sole', 'r_sole'), ('', '')):
        same = FootWrenches(robot, (), 0.015, 0.003).read(
            _sample(robot, reading, reading, frames), None, q, None, {}, [])
        assert same['l'] == reading.tolist() and same['r'] == reading.tolist()


@pytest.mark.parametrize('reading', [None, np.zeros(5), np.array([0, 0, np.nan, 0, 0, 0.0]),
                                     np.array([0, 0, 100.0, np.inf, 0, 0])])
def test_a_missing_or_faulty_reading_is_no_wrench(robot, reading):
    found = FootWrenches(robot, (), 0.015, 0.003).read(_sample(robot, reading, np.ones(6)), None,
                                                       robot.configuration(np.zeros(26)), None, {}, [])
    assert found == {'l': None, 'r': [1.0] * 6}


def test_an_unknown_frame_is_refused_each_time_it_is_named(robot):
    feet = FootWrenches(robot, (), 0.015, 0.003)
    for _ in range(2):
        with pytest.raises(DescriptionError, match="left foot force sensor frame 'ft_left'"):
            feet.read(_sample(robot, np.ones(6), None, ('ft_left', '')), None, None, None, {}, [])


def test_all_finite():
    assert all_finite(np.arange(30.0)) and all_finite(np.zeros(0))
    for bad in (np.nan, np.inf, -np.inf):
        values = np.arange(30.0)
        values[17] = bad
        with np.errstate(invalid='ignore'):
            assert not all_finite(values)
