"""The 12-joint policy's model on the 29-joint G1: what the estimate loses by leaving the held
joints out (method §12, "A Unitree humanoid's own topic").

Unitree's policy walks the real G1 (29 joints) with waist and arms held at their targets; its
model (``g1_unitree_rl_model.json``) was trained on the 12-joint description (``g1_12dof``: legs
only, waist and arms fixed to the pelvis). A G1 owner runs that profile on the robot's
``lowstate``: the estimator reads the legs and ignores the held joints. :func:`held_joint_errors`
measures the price on one run re-encoded as the robot's ``lowstate``: the same messages through
the estimator on the 12-joint description (what the monitor runs) and on the 29-joint one with
the held joints as the motors report them (the robot as it is), per sample; the difference of
CoM, linear and angular momentum, CoP and contact mode, summarised by
:func:`~fall_predictor.data.estimation.summarise` (``benchmarks/bench_g1_held_joints.py`` writes
``docs/estimation/g1_held_joints.json``).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from fall_predictor.data.estimation import BagEstimate, error_samples, summarise
from fall_predictor.monitor.lowstate import LowStateConverter
from fall_predictor.monitor.records import Measurement
from fall_predictor.monitor.sensor_pipeline import SensorPipeline
from fall_predictor.profiles.profile import load_profile

#: The profile a G1 owner runs under Unitree's policy, and the robot's full description.
POLICY_PROFILE = 'g1_12dof'
FULL_PROFILE = 'g1'
#: The robot's variant (mode_machine) both profiles describe.
MODE_MACHINE = 5


def lowstate_estimates(records: Sequence, robot: str) -> dict[int, Measurement]:
    """The estimates of ``records`` ((receive time [ns], LowStateRecord)) on robot ``robot``'s
    profile, by stamp [ns] (samples without one left out)."""
    profile = load_profile(robot)
    layout = profile.sensor_layout()
    converter = LowStateConverter(profile.unitree_hg, layout.imu_frame, profile.joint_names)
    pipeline = SensorPipeline(layout.description(profile.urdf_xml()), layout.imu_frame,
                              layout.force_sensors)
    out = {}
    for receive_ns, record in records:
        sample = converter.convert(record, receive_ns)
        if sample is None:
            continue
        for e in pipeline.lowstate(sample):
            if e.measurement is not None:
                out[e.stamp_ns] = e.measurement
    return out


def held_joint_errors(readings: Sequence, t_push_s: float, seed: int = 0) -> dict[str, np.ndarray]:
    """One simulated run's readings (the policy's robot) as the G1's ``lowstate`` (held joints at
    their targets with the encoders' noise), estimated on the 29-joint description against the
    12-joint one: per-sample differences (:func:`~fall_predictor.data.estimation.error_samples`,
    the 12-joint estimate in the place of the truth)."""
    from fall_predictor.sim.lowstate_driver import BoardTiming, lowstate_records
    policy = load_profile(POLICY_PROFILE)
    records = list(lowstate_records(readings, policy.unitree_hg, MODE_MACHINE, BoardTiming(seed=seed)))
    twelve = lowstate_estimates(records, POLICY_PROFILE)
    full = lowstate_estimates(records, FULL_PROFILE)
    stamps = sorted(set(twelve) & set(full))
    start_ns = records[0][0]
    t = np.array([(s - start_ns) / 1e9 + readings[0].t for s in stamps])
    out = error_samples(BagEstimate(t, [full[s] for s in stamps], [twelve[s] for s in stamps]),
                        t_push_s)
    # The momenta differ by the masses (33.34 against 32.11 kg) as much as by the motion: the CoM
    # velocity says how far the motion estimates agree.
    m_full, m_twelve = (load_profile(r).total_mass_kg for r in (FULL_PROFILE, POLICY_PROFILE))
    out['com_velocity_m_s'] = np.array([np.linalg.norm(full[s].lin_mom / m_full
                                                       - twelve[s].lin_mom / m_twelve)
                                        for s in stamps])
    return out


def summarise_held(per_run: list[dict[str, np.ndarray]]) -> dict:
    """The JSON of :func:`held_joint_errors` over runs: the estimation summary's quantities
    and the CoM velocity's difference (median, p99, and over the post-push windows)."""
    result = summarise(per_run)
    v = np.concatenate([r['com_velocity_m_s'] for r in per_run])
    post = np.concatenate([r['post_push'] for r in per_run])
    result['com_velocity_m_s'] = {
        'median': float(np.median(v)), 'p99': float(np.percentile(v, 99)),
        'post_push_median': float(np.median(v[post])), 'post_push_p99': float(np.percentile(v[post], 99))}
    return result
