"""monitor.sensor_sync's joint table: merged messages, the oldest stamp, stuck joints, efforts."""
import numpy as np
import pytest

from fall_predictor.monitor.sensor_records import JointStateReading
from fall_predictor.monitor.sensor_sync import JointTable, SyncConfig

NAMES = ('a', 'b', 'c', 'd')
MS = 1_000_000
CONFIG = SyncConfig(stuck_time_s=0.1, stuck_speed_rad_s=0.5)


def _reading(stamp_ns, names, q, dq=None, tau=None):
    return JointStateReading(stamp_ns, tuple(names), np.asarray(q, dtype=float),
                             np.zeros(0) if dq is None else np.asarray(dq, dtype=float),
                             np.zeros(0) if tau is None else np.asarray(tau, dtype=float))


def test_split_messages_merge_and_the_oldest_stamp_is_the_lagging_groups():
    table = JointTable(NAMES)
    table.update(_reading(10 * MS, ('b', 'a'), [2.0, 1.0], [0.0, 0.0]))
    assert not table.all_received
    assert table.faults(10 * MS, CONFIG) == ['joints c, d never received']
    table.update(_reading(11 * MS, ('d', 'c'), [4.0, 3.0], [0.0, 0.0]))
    assert table.all_received and table.oldest_stamp_ns == 10 * MS
    np.testing.assert_array_equal(table.q, [1.0, 2.0, 3.0, 4.0])
    table.update(_reading(12 * MS, ('a', 'b'), [1.5, 2.5], [0.0, 0.0]))
    assert table.oldest_stamp_ns == 11 * MS          # c and d now lag
    table.update(_reading(13 * MS, NAMES, [1.0, 2.0, 3.0, 4.0], [0.0] * 4))
    assert table.oldest_stamp_ns == 13 * MS          # a message with every joint
    # Joints silent beyond the timeout are named.
    table.update(_reading(70 * MS, ('a', 'b'), [1.0, 2.0], [0.0, 0.0]))
    assert table.faults(70 * MS, CONFIG) == ['joints c, d not received for more than 50 ms']


def test_a_joint_stuck_from_its_first_reading_is_named_after_the_stuck_time():
    table = JointTable(NAMES)
    # Joint c repeats one position while reporting 1 rad/s; the others move.
    for k in range(150):
        t = k * MS
        table.update(_reading(t, NAMES, [k * 1e-3, k * 2e-3, 0.3, k * 3e-3], [1.0, 2.0, 1.0, 3.0]))
        faults = table.faults(t, CONFIG)
        if t < 100 * MS:
            assert faults == [], (k, faults)
    assert len(faults) == 1 and faults[0].startswith('joint c stuck at 0.3 rad for 0.15 s')
    # It moves again: no longer stuck.
    table.update(_reading(150 * MS, NAMES, [0.15, 0.3, 0.31, 0.45], [1.0, 2.0, 1.0, 3.0]))
    assert table.faults(150 * MS, CONFIG) == []


def test_non_finite_values_are_refused_and_leave_the_table_unchanged():
    table = JointTable(NAMES)
    table.update(_reading(1 * MS, NAMES, [1.0, 2.0, 3.0, 4.0], [0.0] * 4))
    for q, dq in (([1.0, np.nan, 3.0, 4.0], [0.0] * 4), ([1.0, 2.0, 3.0, 4.0], [0.0, np.inf, 0, 0])):
        with pytest.raises(ValueError, match='not finite'):
            table.update(_reading(2 * MS, NAMES, q, dq))
    np.testing.assert_array_equal(table.q, [1.0, 2.0, 3.0, 4.0])
    assert table.oldest_stamp_ns == 1 * MS


def test_unknown_names_are_reported_once_and_efforts_need_every_joint():
    table = JointTable(NAMES)
    assert table.update(_reading(1 * MS, ('a', 'x', 'b'), [1.0, 9.0, 2.0], tau=[1.0, 9.0, 2.0])) == ['x']
    assert table.update(_reading(2 * MS, ('a', 'x', 'b'), [1.0, 9.0, 2.0], tau=[1.0, 9.0, 2.0])) == []
    assert table.efforts().size == 0                 # c and d have none yet
    table.update(_reading(3 * MS, ('c', 'd'), [3.0, 4.0], tau=[3.0, 4.0]))
    np.testing.assert_array_equal(table.efforts(), [1.0, 2.0, 3.0, 4.0])
    table.update(_reading(4 * MS, ('c', 'd'), [3.0, 4.0]))    # a driver without efforts
    assert table.efforts().size == 0
