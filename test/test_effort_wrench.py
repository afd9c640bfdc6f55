"""Foot wrenches without F/T sensors (monitor.effort_wrench): a known answer on the G1's URDF, and
the estimator on the simulated robot's efforts against its contact forces (as the F/T path is)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from fall_predictor.monitor.contact_modes import classify_contact_mode
from fall_predictor.monitor import effort_wrench
from fall_predictor.monitor.effort_wrench import EffortWrench, leg_joint_ids
from fall_predictor.monitor.estimator import StateEstimator
from fall_predictor.monitor.records import PushSpec
from fall_predictor.monitor.robot_description import slice_if_consecutive
from fall_predictor.profiles.profile import load_profile
from fall_predictor.sim.sensors import SensorParams, apply_sensors
from fall_predictor.sim.trajectory import run_trajectory


def _g1():
    profile = load_profile('g1')
    return profile, profile.sensor_layout().description(profile.urdf_xml())


def test_index_arrays_become_slices_only_when_they_count_up_by_one():
    assert slice_if_consecutive(np.array([6, 7, 8])) == slice(6, 9)
    for index in (np.array([6, 8, 9]), np.array([8, 7, 6]), np.array([], dtype=int)):
        assert slice_if_consecutive(index) is index
    # The G1's legs: each a run of velocity columns, taken as a slice of the same columns.
    _, robot = _g1()
    wrench = EffortWrench(robot)
    for side in ('l', 'r'):
        columns = np.arange(robot.model.nv)
        assert isinstance(wrench._leg_cols[side], slice)
        np.testing.assert_array_equal(columns[wrench._leg_cols[side]], wrench.leg_v[side])


def test_the_legs_are_the_joints_of_each_foot_alone():
    profile, robot = _g1()
    for side in ('l', 'r'):
        names = [robot.model.names[j] for j in leg_joint_ids(robot, side)]
        assert sorted(names) == sorted(profile.leg_joints(side))


def test_g1_wrenches_from_efforts_are_the_known_ones():
    """Efforts made from chosen sole wrenches by the whole-body equation of motion (standing still,
    base tilted, knees bent): the legs' efforts alone give those wrenches back."""
    profile, robot = _g1()
    model, data = robot.model, robot.model.createData()
    q_joints = np.zeros(len(robot.joint_names))
    for side in ('l', 'r'):
        hip, _, _, knee, ankle, _ = profile.leg_joints(side)
        for name, angle in ((hip, -0.35), (knee, 0.7), (ankle, -0.35)):
            q_joints[robot.joint_names.index(name)] = angle
    q = robot.configuration(q_joints)
    rot = pin.rpy.rpyToMatrix(0.05, -0.08, 0.3)
    q[3:7] = pin.Quaternion(rot).coeffs()
    truth = {'l': np.array([12.0, -5.0, 190.0, 3.0, -4.0, 0.5]),
             'r': np.array([-8.0, 6.0, 137.0, -2.0, 6.0, -0.3])}
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    tau = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv)).copy()
    for side, wrench in truth.items():
        tau -= pin.getFrameJacobian(model, data, robot.sole_ids[side], pin.ReferenceFrame.LOCAL).T @ wrench
    efforts = tau[robot.idx_v]
    got = EffortWrench(robot).wrenches(q, np.zeros(model.nv), efforts)
    for side in ('l', 'r'):
        assert got[side] == pytest.approx(truth[side], abs=1e-6)


@pytest.mark.parametrize('solve', ['gufunc', 'public'])
def test_straight_knees_give_the_minimum_norm_wrench(solve, monkeypatch):
    """Straight legs (all joints at zero): each leg's 6 x 6 system is singular, and the answer is
    numpy's least-squares, minimum-norm solution of the same system, not an explosion; also where
    only numpy's public solve exists (it raises on a singular system instead of giving NaN)."""
    if solve == 'public':
        monkeypatch.setattr(effort_wrench, '_solve', np.linalg.solve)
    _, robot = _g1()
    model, data = robot.model, robot.model.createData()
    q = robot.configuration(np.zeros(len(robot.joint_names)))
    efforts = np.linspace(-5.0, 5.0, len(robot.joint_names))
    effort = EffortWrench(robot)
    got = effort.wrenches(q, np.zeros(model.nv), efforts)
    b = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv))
    pin.computeJointJacobians(model, data, q)
    for side in ('l', 'r'):
        legs = effort.leg_v[side]
        jac = pin.getFrameJacobian(model, data, robot.sole_ids[side], pin.ReferenceFrame.LOCAL)[:, legs]
        expected = np.linalg.lstsq(jac.T, b[legs] - efforts[effort.leg_tau[side]], rcond=1e-6)[0]
        singular_values = np.linalg.svd(jac, compute_uv=False)
        assert singular_values[-1] < 1e-6 * singular_values[0]      # singular as lstsq sees it
        assert got[side] == pytest.approx(expected, abs=1e-6)


def test_g1_statics_without_efforts_share_the_weight_by_the_lever_rule():
    profile, robot = _g1()
    q = robot.configuration(np.zeros(len(robot.joint_names)))
    effort = EffortWrench(robot)
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    sole_pos = {s: data.oMf[robot.sole_ids[s]].translation.copy() for s in ('l', 'r')}
    sole_rot = {s: np.eye(3) for s in ('l', 'r')}
    com = pin.centerOfMass(robot.model, data, q)
    got = effort.kinematic(com, sole_pos, sole_rot, 0.01)
    weight = robot.total_mass_kg * 9.81
    lam = (com[1] - sole_pos['l'][1]) / (sole_pos['r'][1] - sole_pos['l'][1])
    assert got['l'][2] == pytest.approx((1 - lam) * weight) and got['r'][2] == pytest.approx(lam * weight)
    # Lift the right sole 2 cm: the left carries everything.
    sole_pos['r'] = sole_pos['r'] + [0.0, 0.0, 0.02]
    got = effort.kinematic(com, sole_pos, sole_rot, 0.01)
    assert got['r'] is None and got['l'][2] == pytest.approx(weight)


@pytest.fixture(scope='module')
def pushed():
    run = run_trajectory(PushSpec(60.0, 0.0, 0.1, 0.8), 1.3, record_sensors=True)
    return run, apply_sensors(run.sensor_truths, SensorParams(), seed=7)


def _cop_errors(estimates, truth):
    errors = [np.linalg.norm((a.cop - b.cop)[:2]) for a, b in zip(estimates, truth)
              if a is not None and np.isfinite(a.cop).all() and np.isfinite(b.cop).all()]
    return np.array(errors)


def test_without_ft_sensors_the_efforts_give_the_contacts(pushed):
    """The simulated robot's noisy efforts (0.5 N m) in place of its F/T sensors, over a walk and a
    push: CoP and contact modes against the simulator's contact forces, beside the F/T path."""
    run, readings = pushed
    profile = load_profile('asimo_like')
    robot = profile.sensor_layout().description(profile.urdf_xml())
    with_ft = StateEstimator(robot, imu_frame=profile.imu_frame).run(readings)
    bare = [replace(r, left_wrench=None, right_wrench=None) for r in readings]
    estimator = StateEstimator(robot, imu_frame=profile.imu_frame, effort_feet=('l', 'r'))
    from_efforts = estimator.run(bare)
    assert estimator.wrench_source == 'efforts'
    truth = run.measurements
    assert sum(m is None for m in from_efforts) <= 5
    cop_ft, cop_effort = _cop_errors(with_ft, truth), _cop_errors(from_efforts, truth)
    assert np.median(cop_effort) <= 0.015 and np.percentile(cop_effort, 90) <= 0.04
    agree = np.mean([classify_contact_mode(a) == classify_contact_mode(b)
                     for a, b in zip(from_efforts, truth) if a is not None])
    assert agree >= 0.93
    com = np.array([np.linalg.norm(a.com - b.com) for a, b in zip(from_efforts, truth) if a is not None])
    assert np.percentile(com, 99) <= 0.015
    print(f'CoP median F/T {np.median(cop_ft) * 1000:.1f} mm, efforts {np.median(cop_effort) * 1000:.1f} mm; '
          f'contact modes agree {agree:.3f}')


def test_without_efforts_statics_still_tell_the_support(pushed):
    run, readings = pushed
    profile = load_profile('asimo_like')
    robot = profile.sensor_layout().description(profile.urdf_xml())
    bare = [replace(r, left_wrench=None, right_wrench=None, tau=np.zeros(0)) for r in readings]
    estimator = StateEstimator(robot, imu_frame=profile.imu_frame, effort_feet=('l', 'r'))
    estimates = estimator.run(bare)
    assert estimator.wrench_source == 'statics'
    truth = run.measurements

    def support(m):
        return (len(m.left_contacts) > 0, len(m.right_contacts) > 0)
    agree = np.mean([support(a) == support(b) for a, b in zip(estimates, truth) if a is not None])
    com = np.array([np.linalg.norm(a.com - b.com) for a, b in zip(estimates, truth) if a is not None])
    cop = _cop_errors(estimates, truth)
    # Support right 95 % of the time (measured 0.952), the CoM as with F/T (the kinematics carry
    # it); the CoP only as well as the CoM's projection tells it (measured median 31 mm).
    assert agree >= 0.93 and np.percentile(com, 99) <= 0.01 and np.median(cop) <= 0.05
    print(f'support agrees {agree:.3f}; CoM p99 {np.percentile(com, 99) * 1000:.1f} mm; '
          f'CoP median {np.median(cop) * 1000:.0f} mm')
