"""Tests of the sample order of a 1 kHz stream (data/sample_order.py), by hand-built streams."""
import pytest

from fall_predictor.data.sample_order import RunTracker, Sample, SampleIntake

N, R, D, O, P = (Sample.NEXT, Sample.NEW_RUN, Sample.REPEAT, Sample.OUT_OF_ORDER,
                 Sample.RESTART_PENDING)


def test_run_tracker_notices_resets_and_repeats():
    runs = RunTracker()
    kinds = [runs.classify(t) for t in (0.0, 0.001, 0.001, 0.002, 0.0, 0.0, 0.001, 0.0005)]
    assert kinds == [Sample.NEXT, Sample.NEXT, Sample.REPEAT, Sample.NEXT, Sample.NEW_RUN,
                     Sample.NEW_RUN, Sample.NEXT, Sample.NEW_RUN]
    assert runs.runs == 3


def test_run_tracker_with_a_start_window_keeps_stray_samples_in_the_run():
    runs = RunTracker(restart_at_zero=False, max_start_t_s=1.0)
    kinds = [runs.classify(t) for t in (0.0, 0.0, 3.0, 2.999, 3.001, 0.0)]
    assert kinds == [Sample.NEXT, Sample.REPEAT, Sample.NEXT, Sample.NEXT, Sample.NEXT,
                     Sample.NEW_RUN]


def test_intake_drops_duplicates_and_out_of_order_samples_and_counts_gaps():
    intake = SampleIntake(0.001)
    kinds = [intake.classify(t) for t in (2.0, 2.001, 2.001, 2.004, 2.002, 2.005)]
    assert kinds == [N, N, D, N, O, N]
    assert intake.last_t == 2.005
    assert (intake.duplicates, intake.out_of_order, intake.missing) == (1, 1, 2)  # 2.002, 2.003


def test_a_single_old_stamp_never_starts_a_new_run():
    intake = SampleIntake(0.001, restart_samples=5)
    for k in range(2819):
        intake.classify(k * 0.001)
    # The case that was found: one sample stamped 0.5 s earlier, and one stamped at t = 0.
    assert intake.classify(2.318) is O
    assert intake.classify(0.0) is P
    assert intake.classify(2.819) is N            # the run goes on; the pending restart is void
    assert intake.runs == 0 and intake.last_t == 2.819


def test_restart_rule_needs_consecutive_increasing_samples_near_zero():
    intake = SampleIntake(0.001, restart_samples=5, restart_window_s=1.0)
    for k in range(3000):
        intake.classify(k * 0.001)
    kinds = [intake.classify(k * 0.001) for k in range(6)]
    assert kinds == [P, P, P, P, R, N]            # the 5th restarts; 4 samples are lost
    assert intake.runs == 1 and intake.last_t == 0.005
    # Old samples far from t = 0 never start a pending restart.
    intake = SampleIntake(0.001, restart_samples=2, restart_window_s=1.0)
    for k in range(3000):
        intake.classify(k * 0.001)
    assert [intake.classify(t) for t in (1.5, 1.501)] == [O, O]
    # A pending restart broken by a non-increasing sample is void.
    assert [intake.classify(t) for t in (0.0, 0.0, 0.001)] == [P, O, P]


def test_explicit_reset_accepts_the_next_sample_whatever_its_time():
    intake = SampleIntake(0.001)
    intake.classify(5.0)
    intake.reset()
    assert intake.classify(0.0) is N and intake.runs == 0
    with pytest.raises(ValueError):
        SampleIntake(0.0)
