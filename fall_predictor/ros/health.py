"""A node's health: ``/diagnostics`` reports, counted and throttled rejections, guarded callbacks,
and how old a sample is on the node's ROS clock."""
from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any, Callable, Optional

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.subscription import Subscription

from fall_predictor.contract.topics import DIAGNOSTICS, DIAGNOSTICS_RATE_HZ
from fall_predictor.monitor.plausibility import bound_text
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.endpoints import create_publisher
from fall_predictor.ros.parameters import ParamSpec

#: Exceptions a message handler catches, counts and reports instead of dying: malformed or
#: implausible values (ValueError, WireFormatError), and numeric failures of conversions
#: (OverflowError, FloatingPointError, ZeroDivisionError are ArithmeticErrors; rclpy raises
#: SystemError when a value does not fit a message field).
HANDLED_ERRORS: tuple[type[BaseException], ...] = (ValueError, ArithmeticError, SystemError)

# --------------------------------------------------------------------------------------------
# Diagnostics
# --------------------------------------------------------------------------------------------

#: /diagnostics key listing the input topics without a matched publisher (space-separated).
UNMATCHED_INPUTS = 'unmatched_inputs'
#: A node's health report: (level, message, key values).
Report = tuple[int, str, Mapping[str, object]]


def steady_clock() -> Clock:
    """A wall clock for watchdogs: never simulation time, never jumps."""
    return Clock(clock_type=ClockType.STEADY_TIME)


class Diagnostics:
    """Publishes ``report()`` on ``/diagnostics`` every ``period_s`` wall seconds.

    The status is named after the node; its header stamp is the node's latest sample time
    (the input stamp it has processed last, ROS time [ns]), from ``sample_stamp_ns()``. The value
    ``unmatched_inputs`` lists the topics of ``inputs`` no publisher is matched with yet
    (empty when every input is connected): a run should start only once it is empty
    everywhere, or its first samples are lost for the unmatched subscriber.
    """

    def __init__(self, node: Node, report: Callable[[], Report],
                 sample_stamp_ns: Callable[[], int], inputs: Sequence[Subscription] = (),
                 errors: Optional['InputErrors'] = None,
                 period_s: float = 1.0 / DIAGNOSTICS_RATE_HZ) -> None:
        self._node = node
        self._errors = errors
        self._report = report
        self._sample_stamp_ns = sample_stamp_ns
        self._inputs = inputs
        self._publisher = create_publisher(node, DiagnosticArray, DIAGNOSTICS)
        self._timer = node.create_timer(period_s, self.publish, clock=steady_clock())

    def publish(self) -> None:
        """Publish the current report now; a numeric failure is counted, never raised."""
        try:
            self._publish()
        except HANDLED_ERRORS as error:
            if self._errors is None:
                raise
            self._errors.reject('diagnostics report', error)

    def _publish(self) -> None:
        level, message, values = self._report()
        unmatched = ' '.join(s.topic_name for s in self._inputs if s.get_publisher_count() == 0)
        status = DiagnosticStatus(
            level=bytes((level,)), name=self._node.get_fully_qualified_name(), message=message,
            hardware_id='fall_predictor',
            values=[KeyValue(key=key, value=str(value)) for key, value in values.items()]
            + [KeyValue(key=UNMATCHED_INPUTS, value=unmatched)])
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = ros_qos.stamp(min(max(0, self._sample_stamp_ns()), ros_qos.MAX_STAMP_NS))
        self._publisher.publish(msg)


#: Why the nodes throttle their log lines themselves: rclpy's logger inspects the caller's
#: stack frame and reads its source file on every call, ~0.4 ms a call on this project's machine
#: even when ``throttle_duration_sec`` then suppresses the line. A node at 1 kHz therefore calls
#: it at most once per throttle period (:class:`InputErrors`, :class:`FaultLog`).
LOG_THROTTLE_S = 1.0


class InputErrors:
    """Counts rejected inputs and logs them, at most one line per ``throttle_s`` (the first at
    once; the count in each line says how many were dropped in between)."""

    def __init__(self, node: Node, throttle_s: float = LOG_THROTTLE_S) -> None:
        self._node = node
        self._throttle_s = throttle_s
        self.count = 0
        self.last: str = ''
        self._reported = 0
        self._logged_at = -float('inf')

    def reject(self, what: str, error: Exception) -> None:
        self.count += 1
        self.last = bound_text(f'{what}: {error}')         # the error may quote wire text
        now = time.monotonic()
        if now - self._logged_at >= self._throttle_s:
            self._logged_at = now
            self._node.get_logger().warning(f'dropped {self.last} ({self.count} dropped so far)')

    def new_since_last_call(self) -> int:
        """Inputs rejected since the previous call (for a periodic health report)."""
        new, self._reported = self.count - self._reported, self.count
        return new


def guarded(what: str) -> Callable[[Callable[..., None]], Callable[..., None]]:
    """Decorator of a node's message callback: the exceptions of :data:`HANDLED_ERRORS` are
    counted and logged by the node's ``_bad_inputs`` (:class:`InputErrors`) as a rejected
    ``what``, never raised into the executor (which would kill the node)."""
    def decorate(method: Callable[..., None]) -> Callable[..., None]:
        def handler(self: Any, *args: Any) -> None:
            try:
                method(self, *args)
            except HANDLED_ERRORS as error:
                self._bad_inputs.reject(what, error)
        handler.__name__ = method.__name__
        handler.__doc__ = method.__doc__
        return handler
    return decorate


class FaultLog:
    """The faults of a node's samples over time, in at most one line per ``throttle_s``.

    A fault after a quiet period is logged at once, a lasting one again every ``throttle_s``
    with how long it has lasted, and its end once. Changes within ``throttle_s`` of the last line
    (a fault that comes and goes with every few samples: a sensor losing messages) are counted
    and summed up in the next line instead of logged one by one: at 1 kHz they would flood the
    log, and each line costs the node a sample's time (:data:`LOG_THROTTLE_S`)."""

    def __init__(self, node: Node, throttle_s: float = LOG_THROTTLE_S) -> None:
        self._node = node
        self._throttle_s = throttle_s
        self._fault = ''
        self._since = 0.0
        self._logged_at = -float('inf')
        self._changes = 0           # changes of the fault since the last line
        self._between = ''          # the last fault since the last line other than the current
        self._ended: tuple[str, float] = ('', 0.0)   # the last fault that ended, how long it lasted

    def update(self, fault: str) -> None:
        """The fault of the latest sample ('' when it had none; bounded as it is logged)."""
        fault = bound_text(fault)
        if fault != self._fault:
            now = time.monotonic()
            if self._fault:
                self._ended = (self._fault, now - self._since)
                self._between = self._fault
            self._changes += 1
            self._fault, self._since = fault, now
        elif not fault and not self._changes:
            return                  # the common case at 1 kHz: no fault, nothing to tell
        else:
            now = time.monotonic()
        if now - self._logged_at < self._throttle_s:
            return
        self._log(now)

    def _log(self, now: float) -> None:
        logger, fault = self._node.get_logger(), self._fault
        changes = self._changes
        also = ''
        if changes > 1:             # (then an earlier line exists: a first change logs at once)
            also = f' (the fault changed {changes} times in the last {now - self._logged_at:.1f} s'
            if self._between and self._between != (fault or self._ended[0]):
                also += f'; also: {self._between}'
            also += ')'
        self._changes = 0
        self._between = ''
        self._logged_at = now
        if fault and changes:
            logger.warning(f'{fault}: no prediction{also}')
        elif fault:
            logger.warning(f'{fault} for {now - self._since:.1f} s: no prediction')
        else:
            ended, lasted_s = self._ended
            logger.info(f'back to normal after {lasted_s:.1f} s of: {ended}{also}')

    def current(self) -> str:
        """The lasting fault with its duration, or ''."""
        return f'{self._fault} for {time.monotonic() - self._since:.1f} s' if self._fault else ''


class SampleAge:
    """How old a sample is when it arrives, on the node's ROS clock: system time on a robot, the
    simulator's ``/clock`` under ``use_sim_time``. Stamps and clock must be ROS time on
    synchronised clocks; when they are not, :meth:`problem` says so in words."""

    def __init__(self, node: Node) -> None:
        self._clock = node.get_clock()
        #: Under ``use_sim_time``, after the input's clock stepped back: the node's clock then,
        #: until ``/clock`` follows the step (ages are unknown meanwhile).
        self._clock_before_step_ns: Optional[int] = None

    def input_stepped_back(self) -> None:
        """The input's clock stepped back (a new run). Under ``use_sim_time`` a simulator reset
        steps ``/clock`` back too, but its first samples may come before the new ``/clock``: until
        the node's clock has stepped back as well, a sample's age is unknown, not late."""
        if self._clock.ros_time_is_active:
            self._clock_before_step_ns = self._clock.now().nanoseconds

    def age_s(self, stamp_ns: int) -> Optional[float]:
        """Seconds since ``stamp_ns`` on the node's clock; None while the clock has no time yet
        (``use_sim_time`` before the first ``/clock``).

        Under ``use_sim_time`` a sample stamped ahead of the clock is 0 s old: the clock is the
        last ``/clock`` this node has taken, and the simulator stamps its samples with its own
        time, so "ahead" means that ``/clock`` reached this node later than the sample, not that
        clocks differ (a loaded machine showed 0.3 s, and the monitor said STALE through a fall)."""
        now = self._clock.now().nanoseconds
        if now == 0:
            return None
        if self._clock_before_step_ns is not None:
            if now >= self._clock_before_step_ns and self._clock.ros_time_is_active:
                return None                 # /clock has not followed the step back yet
            self._clock_before_step_ns = None
        age_s = (now - stamp_ns) / 1e9
        return 0.0 if age_s < 0.0 and self._clock.ros_time_is_active else age_s

    @staticmethod
    def problem(age_s: Optional[float], limit_s: float) -> Optional[str]:
        """Why a sample of age ``age_s`` cannot be used with ``max_sample_age_s`` = ``limit_s``
        (0: no check), or None."""
        if age_s is None or limit_s <= 0.0 or -limit_s <= age_s <= limit_s:
            return None
        if age_s > 0.0:
            return (f'sample arrived {age_s:.3f} s after its stamp (max_sample_age_s {limit_s:g}); '
                    'if every sample does, the clocks of the robot and of this computer differ')
        return (f'sample stamped {-age_s:.3f} s ahead of this computer\'s clock: its ROS time and '
                'the robot\'s are not synchronised (chrony/PTP), so ages cannot be checked')


MAX_SAMPLE_AGE = ParamSpec(
    'max_sample_age_s', 0.05, 'a sample whose stamp differs from the node\'s ROS clock by more than '
    'this when it arrives [s] gets a STALE state instead of a prediction (0 = no check; under '
    'use_sim_time only a late one)', 0.0, 10.0)
