"""ros/health.py: the nodes' own log throttling (rclpy's logger costs ~0.4 ms a call, even a
suppressed one), on a fake clock and a recording logger."""
from __future__ import annotations

import pytest

from fall_predictor.ros import health
from fall_predictor.ros.health import FaultLog, InputErrors


class _Logger:
    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def warning(self, message: str, **filters: object) -> None:
        assert not filters, 'rclpy filters cost ~0.4 ms a call: the nodes throttle themselves'
        self.lines.append(('warning', message))

    def info(self, message: str, **filters: object) -> None:
        assert not filters
        self.lines.append(('info', message))


class _Node:
    def __init__(self) -> None:
        self.logger = _Logger()

    def get_logger(self) -> _Logger:
        return self.logger


class _Clock:
    """Whole milliseconds (no rounding drift over thousands of steps)."""

    def __init__(self) -> None:
        self.now_ms = 100_000

    def __call__(self) -> float:
        return self.now_ms / 1000.0


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> _Clock:
    fake = _Clock()
    monkeypatch.setattr(health.time, 'monotonic', fake)
    return fake


def test_input_errors_log_the_first_rejection_at_once_then_one_line_a_second(clock: _Clock
                                                                             ) -> None:
    node = _Node()
    errors = InputErrors(node)
    for k in range(2500):                       # 2.5 s of a bad input at 1 kHz
        errors.reject('imu', ValueError(f'bad {k}'))
        clock.now_ms += 1
    assert errors.count == 2500 and errors.last == 'imu: bad 2499'
    assert [line for _, line in node.logger.lines] == [
        'dropped imu: bad 0 (1 dropped so far)', 'dropped imu: bad 1000 (1001 dropped so far)',
        'dropped imu: bad 2000 (2001 dropped so far)']


def test_a_fault_that_comes_and_goes_every_sample_is_summed_up_not_logged_each_time(
        clock: _Clock) -> None:
    """A sensor losing every other message for 2 s at 1 kHz: 2000 changes of the fault, three
    lines (the first at once, then one a second saying how often it changed), not 2000."""
    node = _Node()
    log = FaultLog(node)
    for k in range(2000):
        log.update('no /imu/data' if k % 2 == 0 else '')
        clock.now_ms += 1
    log.update('')                              # at 2.0 s: normal, a line is due
    assert node.logger.lines == [
        ('warning', 'no /imu/data: no prediction'),
        ('warning', 'no /imu/data: no prediction (the fault changed 1000 times in the last 1.0 s)'),
        ('info', 'back to normal after 0.0 s of: no /imu/data '
                 '(the fault changed 999 times in the last 1.0 s)')]


def test_a_lasting_fault_is_repeated_each_second_with_its_duration_and_its_end_logged_once(
        clock: _Clock) -> None:
    node = _Node()
    log = FaultLog(node)
    for _ in range(2500):
        log.update('IMU stuck')
        clock.now_ms += 1
    assert log.current() == 'IMU stuck for 2.5 s'
    for _ in range(3000):                       # 3 s without a fault: one line
        log.update('')
        clock.now_ms += 1
    assert node.logger.lines == [('warning', 'IMU stuck: no prediction'),
                                 ('warning', 'IMU stuck for 1.0 s: no prediction'),
                                 ('warning', 'IMU stuck for 2.0 s: no prediction'),
                                 ('info', 'back to normal after 2.5 s of: IMU stuck')]
    assert log.current() == ''


def test_a_new_fault_after_a_quiet_second_is_logged_at_once(clock: _Clock) -> None:
    node = _Node()
    log = FaultLog(node)
    log.update('no /left_foot/wrench')
    clock.now_ms += 200
    log.update('')                              # within the second: held back
    assert len(node.logger.lines) == 1
    clock.now_ms += 1000
    log.update('')                              # due: the end, once
    clock.now_ms += 5000
    log.update('IMU stuck')                     # after a quiet period: at once
    assert node.logger.lines == [('warning', 'no /left_foot/wrench: no prediction'),
                                 ('info', 'back to normal after 0.2 s of: no /left_foot/wrench'),
                                 ('warning', 'IMU stuck: no prediction')]


def test_a_summary_names_another_fault_that_came_and_went_in_between(clock: _Clock) -> None:
    node = _Node()
    log = FaultLog(node)
    log.update('')
    log.update('no features received')              # logged at once
    clock.now_ms += 100
    log.update('sample arrived 0.200 s after its stamp')
    clock.now_ms += 100
    log.update('')
    clock.now_ms += 1000
    log.update('no features received')              # due: the summary names the one between
    assert node.logger.lines[-1] == (
        'warning', 'no features received: no prediction (the fault changed 3 times in the last '
                   '1.2 s; also: sample arrived 0.200 s after its stamp)')


class _ClockNode:
    """A node whose clock is rclpy's ROS clock, system time or (``sim_time_ns``) an overridden
    simulation time, as ``use_sim_time`` sets it from ``/clock``."""

    def __init__(self, sim_time_ns: int | None = None) -> None:
        from rclpy.clock import ROSClock
        from rclpy.time import Time
        self.clock = ROSClock()
        if sim_time_ns is not None:
            self.clock._set_ros_time_is_active(True)
            self.clock.set_ros_time_override(Time(nanoseconds=sim_time_ns))

    def get_clock(self):
        return self.clock


def test_a_sample_ahead_of_a_simulation_clock_is_fresh_not_from_unsynchronised_clocks() -> None:
    # /clock says 2.500 s; the simulator's sample of 2.794 s got here first.
    age = health.SampleAge(_ClockNode(sim_time_ns=2_500_000_000))
    assert age.age_s(2_794_000_000) == 0.0
    assert health.SampleAge.problem(age.age_s(2_794_000_000), 0.05) is None
    # Late on the simulation's clock is still late.
    assert age.age_s(2_400_000_000) == pytest.approx(0.1)
    assert 'after its stamp' in health.SampleAge.problem(age.age_s(2_400_000_000), 0.05)


def test_a_sample_ahead_of_system_time_says_the_clocks_are_not_synchronised() -> None:
    import time
    age = health.SampleAge(_ClockNode())
    ahead = age.age_s(time.time_ns() + 300_000_000)
    assert ahead == pytest.approx(-0.3, abs=0.05)
    assert 'not synchronised (chrony/PTP)' in health.SampleAge.problem(ahead, 0.05)
