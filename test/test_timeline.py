"""The time rule (monitor/timeline.py) on stamps as robots publish them."""
from __future__ import annotations

import numpy as np
import pytest

from fall_predictor.monitor.timeline import NS_PER_S, Stamp, StampTimeline, TimelineConfig

#: 2026-11-24 12:00:00 UTC in ROS time [ns]: an epoch stamp as a robot's drivers publish it.
EPOCH_NS = 1_795_521_600 * NS_PER_S + 123_456_789
MS = 1_000_000


def stream(timeline: StampTimeline, stamps) -> list[Stamp]:
    return [timeline.classify(int(s)) for s in stamps]


def test_epoch_stamps_give_exact_run_times_from_the_first_sample() -> None:
    timeline = StampTimeline()
    kinds = stream(timeline, [EPOCH_NS + k * 2 * MS for k in range(1000)])   # 500 Hz, 2 s
    assert set(kinds) == {Stamp.NEXT}
    assert timeline.anchor_ns == EPOCH_NS
    # Run time is exact to the nanosecond (integer difference first, then seconds).
    assert timeline.run_time(EPOCH_NS + 1_998_000_001) == 1.998000001
    assert timeline.last_run_time() == pytest.approx(1.998, abs=1e-12)
    assert timeline.period_s == pytest.approx(0.002)
    assert timeline.counters() == {'duplicates': 0, 'out_of_order': 0, 'stray_stamps': 0,
                                   'clock_jumps': 0, 'pauses': 0, 'missing_samples': 0}


def test_duplicates_and_out_of_order_samples_are_dropped_and_counted() -> None:
    timeline = StampTimeline()
    kinds = stream(timeline, [EPOCH_NS, EPOCH_NS + MS, EPOCH_NS + MS, EPOCH_NS + 2 * MS,
                              EPOCH_NS + MS // 2, EPOCH_NS + 3 * MS])
    assert kinds == [Stamp.NEXT, Stamp.NEXT, Stamp.DUPLICATE, Stamp.NEXT, Stamp.OUT_OF_ORDER,
                     Stamp.NEXT]
    assert (timeline.duplicates, timeline.out_of_order, timeline.last_ns) == (1, 1, EPOCH_NS + 3 * MS)
    assert timeline.strays == 0                             # counted once, as out of order


def test_a_simulator_restarting_its_clock_soon_after_the_start_is_a_new_run() -> None:
    # A world reset 0.3 s after the start: time goes back by less than max_step_s. The samples
    # of the new world are consistent with each other: after jump_samples of them, a new run.
    timeline = StampTimeline(TimelineConfig(max_step_s=0.5, jump_samples=5))
    stream(timeline, [k * MS for k in range(300)])
    kinds = stream(timeline, [k * MS for k in range(6)])
    assert kinds == [Stamp.OUT_OF_ORDER] * 4 + [Stamp.NEW_RUN, Stamp.NEXT]
    assert (timeline.anchor_ns, timeline.jumps, timeline.out_of_order) == (4 * MS, 1, 4)


@pytest.mark.parametrize('stray_ns', [
    EPOCH_NS + 1000 * NS_PER_S,                   # 1000 s in the future
    EPOCH_NS - 86_400 * NS_PER_S,                 # a day in the past
    (2 ** 31 - 1) * NS_PER_S,                     # sec = 2^31 - 1
    0,                                            # the epoch itself
])
def test_one_stray_stamp_neither_blinds_the_timeline_nor_starts_a_run(stray_ns: int) -> None:
    timeline = StampTimeline()
    stream(timeline, [EPOCH_NS + k * MS for k in range(100)])
    assert timeline.classify(stray_ns) is Stamp.JUMP_PENDING
    kinds = stream(timeline, [EPOCH_NS + k * MS for k in range(100, 200)])
    assert set(kinds) == {Stamp.NEXT}                       # not blinded
    assert timeline.anchor_ns == EPOCH_NS                   # the same run
    assert (timeline.strays, timeline.jumps) == (1, 0)


def test_a_clock_set_back_re_anchors_after_jump_samples_consistent_samples() -> None:
    timeline = StampTimeline(TimelineConfig(max_step_s=0.5, jump_samples=5))
    stream(timeline, [EPOCH_NS + k * MS for k in range(100)])
    back = EPOCH_NS - 3600 * NS_PER_S                       # NTP stepped the clock back an hour
    kinds = stream(timeline, [back + k * MS for k in range(10)])
    assert kinds == [Stamp.JUMP_PENDING] * 4 + [Stamp.NEW_RUN] + [Stamp.NEXT] * 5
    assert timeline.anchor_ns == back + 4 * MS
    assert timeline.run_time(back + 9 * MS) == pytest.approx(0.005)
    assert (timeline.jumps, timeline.strays) == (1, 0)


def test_a_sensor_that_pauses_or_a_clock_stepped_forward_starts_a_new_run() -> None:
    """A step forward beyond max_step_s is held for one sample: followed on, the stream paused or
    its clock stepped forward, and a new run starts at the follower (the samples in between
    counted missing); not followed, a stray."""
    timeline = StampTimeline(TimelineConfig(max_step_s=0.5))
    stream(timeline, [EPOCH_NS + k * MS for k in range(100)])
    resumed = EPOCH_NS + 2099 * MS                          # 2 s without samples
    assert timeline.classify(resumed) is Stamp.JUMP_PENDING
    assert timeline.classify(resumed + MS) is Stamp.NEW_RUN
    assert timeline.missing == 2000 and timeline.anchor_ns == resumed + MS
    assert (timeline.pauses, timeline.jumps) == (1, 0)
    assert timeline.last_step_s == pytest.approx(1.999)    # beyond where the next sample was due
    assert timeline.run_time(resumed + 3 * MS) == pytest.approx(0.002)
    # An hour forward (NTP): the same, a new run.
    ahead = resumed + 3600 * NS_PER_S
    assert [timeline.classify(ahead + k * MS) for k in range(3)] == [
        Stamp.JUMP_PENDING, Stamp.NEW_RUN, Stamp.NEXT]
    assert timeline.anchor_ns == ahead + MS and timeline.strays == 0 and timeline.pauses == 2
    # A stray from the past held while the sensor paused is still counted.
    assert timeline.classify(EPOCH_NS - NS_PER_S) is Stamp.JUMP_PENDING
    assert [timeline.classify(ahead + NS_PER_S + k * MS) for k in range(2)] == [
        Stamp.JUMP_PENDING, Stamp.NEW_RUN]
    assert timeline.strays == 1


def test_a_restart_from_upstream_anchors_at_once() -> None:
    """A consumer of a producer that applies the rule takes its new run without confirming it."""
    timeline = StampTimeline()
    stream(timeline, [EPOCH_NS + k * MS for k in range(10)])
    back = EPOCH_NS - 10 * NS_PER_S
    timeline.restart(back)
    assert timeline.anchor_ns == back and timeline.jumps == 1
    assert timeline.last_step_s == pytest.approx(-10.010)
    assert timeline.classify(back + MS) is Stamp.NEXT


def test_strays_that_disagree_with_each_other_never_confirm_a_jump() -> None:
    timeline = StampTimeline(TimelineConfig(jump_samples=3))
    stream(timeline, [EPOCH_NS + k * MS for k in range(10)])
    rng = np.random.default_rng(0)
    # Garbage stamps, far from the run and from each other, interleaved with no valid samples.
    garbage = rng.integers(0, 2 ** 62, size=50)
    assert set(stream(timeline, garbage)) == {Stamp.JUMP_PENDING}
    assert timeline.jumps == 0 and timeline.anchor_ns == EPOCH_NS
    assert timeline.classify(EPOCH_NS + 10 * MS) is Stamp.NEXT


def test_a_stray_first_sample_heals_after_jump_samples() -> None:
    timeline = StampTimeline(TimelineConfig(jump_samples=5))
    assert timeline.classify((2 ** 31 - 1) * NS_PER_S) is Stamp.NEXT    # anchors on it
    kinds = stream(timeline, [EPOCH_NS + k * MS for k in range(6)])
    assert kinds == [Stamp.JUMP_PENDING] * 4 + [Stamp.NEW_RUN, Stamp.NEXT]
    assert timeline.anchor_ns == EPOCH_NS + 4 * MS


def test_gaps_are_counted_on_the_streams_own_period_despite_jitter() -> None:
    rng = np.random.default_rng(1)
    period = 2 * MS                                          # 500 Hz, 0.2 ms jitter
    grid = EPOCH_NS + np.arange(2000) * period
    stamps = grid + rng.integers(-200_000, 200_000, size=grid.size)
    kept = np.ones(grid.size, dtype=bool)
    kept[[500, 900, 901, 902, 1500]] = False                 # 5 samples lost
    timeline = StampTimeline()
    assert set(stream(timeline, stamps[kept])) == {Stamp.NEXT}
    assert timeline.missing == 5
    assert timeline.period_s == pytest.approx(0.002, rel=0.02)


def test_reset_anchors_the_next_stamp_whatever_it_is() -> None:
    timeline = StampTimeline()
    stream(timeline, [EPOCH_NS + k * MS for k in range(10)])
    timeline.reset()
    assert timeline.classify(5 * MS) is Stamp.NEXT and timeline.anchor_ns == 5 * MS


@pytest.mark.parametrize('kwargs', [{'max_step_s': 0.0}, {'max_step_s': float('nan')},
                                    {'jump_samples': 0}, {'jump_samples': 2.5}])
def test_bad_configurations_are_refused(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        TimelineConfig(**kwargs)


def test_the_period_is_learnt_even_when_the_first_step_is_a_gap() -> None:
    timeline = StampTimeline()
    timeline.classify(EPOCH_NS)
    stream(timeline, [EPOCH_NS + 300 * MS + k * MS for k in range(50)])   # 0.3 s, then 1 kHz
    assert timeline.period_s == pytest.approx(0.001)
    # A 1 s pause: the first sample after it is held, the next confirms it (a new run); every
    # sample in between (the held one too) is missing.
    assert stream(timeline, [EPOCH_NS + 1349 * MS, EPOCH_NS + 1350 * MS]) == [Stamp.JUMP_PENDING,
                                                                             Stamp.NEW_RUN]
    assert timeline.missing == 1000
