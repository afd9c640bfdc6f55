

def test_the_29_joint_state_with_held_joints_matches_the_12_joint_models_estimate(runs):
    """The bounds docs/method.md §12 states (benchmarks/bench_lowstate_g1.py measures them on 20
    held-out runs): CoM within 1.5 cm, CoM velocity within 0.06 m/s (p99), the same contact mode
    at 99 % of the samples, angular momentum within 0.05 kg m^2/s (median)."""
    from fall_predictor.data.held_joints import held_joint_errors, summarise_held
    summary = summarise_held([held_joint_errors(runs[name].sensor_readings, PUSH_AT_S, seed=k)
                              for k, (name, *_) in enumerate(RUNS)])
    assert summary['com_m']['p99'] <= 0.015, summary['com_m']
    assert summary['com_velocity_m_s']['p99'] <= 0.06, summary['com_velocity_m_s']
    assert summary['contact_mode_agreement'] >= 0.99
    assert summary['angular_momentum_kg_m2_s']['median'] <= 0.05
