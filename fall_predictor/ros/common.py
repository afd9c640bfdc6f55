"""Plumbing shared by the fall_predictor nodes: parameters, run detection, diagnostics, main().

The nodes are thin rclpy wrappers around the core library; this module holds what they have
in common so that each node file only says what is specific to it:

* :class:`ParamSpec` / :func:`declare_parameters`: parameters declared with a
  ``ParameterDescriptor`` (range, description, read-only flag) and validated by an
  ``on_set_parameters`` callback that rejects bad values with a reason;
* :class:`SampleIntake`: orders one 1 kHz stream of sample times: duplicates and
  out-of-order samples are dropped and counted, missing samples (gaps) are counted, and a new
  run starts only by an explicit reset or by the restart rule, which a single old stamp
  cannot meet; :class:`SampleAge` measures how late a sample arrives;
* :class:`Diagnostics`: a 1 Hz ``/diagnostics`` status per node (wall-clock timer);
* :func:`run_node`: the ``main()`` body of every node (SingleThreadedExecutor, clean
  shutdown, a clear one-line error and exit code 1 when the node cannot start).

It also defines the one topic that is not part of :mod:`fall_predictor.data.wire`: the push
request (:data:`PUSH_REQUEST`), an input of the simulator node.
"""
from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Optional, Union

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos_overriding_options import QoSOverridingOptions
from rclpy.subscription import Subscription

from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.monitor.features import FeatureSettings, FeatureSettingsMismatch
from fall_predictor.monitor.model_file import (DEFAULT_MAX_MODEL_BYTES, ModelFileError,
                                              ModelMetadata, load_model)
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.share import default_model_path
from fall_predictor.data.topics import DIAGNOSTICS, DIAGNOSTICS_RATE_HZ, SIM_RATE_HZ, TopicSpec

#: Period of the 1 kHz sample streams [s] (the simulator's step).
SAMPLE_PERIOD_S = 1.0 / SIM_RATE_HZ
ParamValue = Union[bool, int, float, str]
#: A cross-parameter check: proposed values of all parameters -> reason to reject, or None.
CrossCheck = Callable[[Mapping[str, ParamValue]], Optional[str]]


#: Exceptions a message handler catches, counts and reports instead of dying: malformed or
#: implausible values (ValueError, WireFormatError), and numeric failures of conversions
#: (OverflowError, FloatingPointError, ZeroDivisionError are ArithmeticErrors; rclpy raises
#: SystemError when a value does not fit a message field).
HANDLED_ERRORS: tuple[type[BaseException], ...] = (ValueError, ArithmeticError, SystemError)


def create_publisher(node: Node, msg_type: type, spec: TopicSpec) -> Publisher:
    """A publisher on ``spec``'s topic (relative name) with its wire QoS.

    The QoS can be overridden by parameters (``qos_overrides.<topic>.publisher.<policy>``,
    rclpy's ``QoSOverridingOptions``). Without rclpy's default QoS-event handlers (incompatible
    QoS / type warnings): each one is a waitable that the executor polls on every wake-up, a
    measurable cost at 1 kHz, and the QoS of every topic comes from
    :mod:`fall_predictor.data.topics`, so they cannot disagree.
    """
    return node.create_publisher(msg_type, spec.ros_name, ros_qos.qos_profile(spec.qos),
                                 event_callbacks=PublisherEventCallbacks(
                                     use_default_callbacks=False),
                                 qos_overriding_options=QoSOverridingOptions.with_default_policies())


def create_subscription(node: Node, msg_type: type, spec: TopicSpec,
                        callback: Callable[[Any], None], raw: bool = False,
                        lossless: bool = False,
                        on_message_lost: Optional[Callable[[Any], None]] = None) -> Subscription:
    """A subscription to ``spec``'s topic (relative name) with the subscriber QoS of the
    contract (best effort, shallow, for sensor streams: REP 2003), or with the publisher's
    reliable deep QoS when ``lossless`` (the recorder). Overridable by parameters like the
    publishers; no QoS-event handlers (see :func:`create_publisher`); ``raw`` delivers the
    serialized bytes; ``on_message_lost`` receives DDS's message-lost events."""
    qos = spec.qos if lossless else spec.subscription_qos
    return node.create_subscription(msg_type, spec.ros_name, callback, ros_qos.qos_profile(qos),
                                    event_callbacks=SubscriptionEventCallbacks(
                                        message_lost=on_message_lost,
                                        use_default_callbacks=False),
                                    raw=raw,
                                    qos_overriding_options=QoSOverridingOptions.with_default_policies())


class BringupError(RuntimeError):
    """The bring-up failed (a node did not start or died, the simulation got stuck)."""


class NodeStartupError(RuntimeError):
    """A node cannot start (missing model, bad configuration); the message says why."""


# --------------------------------------------------------------------------------------------
# Parameters
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ParamSpec:
    """One node parameter: default (its type is the parameter's type), description with the
    unit, optional inclusive range [low, high] for numbers, and whether it is read-only
    (settable only at start-up, from a params file or ``-p``)."""

    name: str
    default: ParamValue
    description: str
    low: Optional[float] = None
    high: Optional[float] = None
    read_only: bool = False
    #: A value below ``low`` that means "not set" (e.g. adopt the model's value), or None.
    unset: Optional[float] = None

    def descriptor(self) -> ParameterDescriptor:
        descriptor = ParameterDescriptor(description=self.description, read_only=self.read_only)
        if self.low is not None and self.high is not None:
            low = self.low if self.unset is None else min(self.low, self.unset)
            if isinstance(self.default, float):
                descriptor.floating_point_range = [
                    FloatingPointRange(from_value=float(low), to_value=float(self.high))]
            elif isinstance(self.default, int) and not isinstance(self.default, bool):
                descriptor.integer_range = [
                    IntegerRange(from_value=int(self.low), to_value=int(self.high), step=1)]
        return descriptor

    def check(self, value: object) -> Optional[str]:
        """Why ``value`` is not acceptable for this parameter, or None if it is."""
        kind = type(self.default)
        if type(value) is not kind:
            return f'{self.name} must be a {kind.__name__}, got {value!r}'
        if isinstance(value, float) and not math.isfinite(value):
            return f'{self.name} must be finite, got {value!r}'
        if self.unset is not None and value == self.unset:
            return None
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            if (self.low is not None and value < self.low) or (
                    self.high is not None and value > self.high):
                unset = '' if self.unset is None else f' (or {self.unset} for unset)'
                return f'{self.name} = {value!r} is outside [{self.low}, {self.high}]{unset}'
        return None

    def value_or_none(self, value: ParamValue) -> Optional[ParamValue]:
        """``value``, or None if it is this parameter's ``unset`` value."""
        return None if self.unset is not None and value == self.unset else value


MODEL_PATH = ParamSpec(
    'model_path', '', 'model file (JSON decision lists); empty = models/default_model.json of '
    'the installed package, else of the source tree', read_only=True)

MAX_MODEL_BYTES = ParamSpec(
    'max_model_bytes', DEFAULT_MAX_MODEL_BYTES, 'largest model file read [bytes]; only regular '
    'files are read (a FIFO or a device is refused)', 1, 2_000_000_000, read_only=True)

#: "Adopt the model's value": the unset value of the feature-settings parameters.
FROM_MODEL = -1.0


def feature_setting_params(names: Sequence[str]) -> tuple[ParamSpec, ...]:
    """Parameters for the model's feature settings (see
    :class:`~fall_predictor.monitor.features.FeatureSettings`), unset by default: a node adopts
    the model's value, and refuses to start if a set value differs from it."""
    specs = {
        'rate_window_s': ParamSpec('rate_window_s', FROM_MODEL, 'backward-difference window of '
                                   'the momentum rates [s]; -1 = the model\'s', 1e-4, 0.1,
                                   read_only=True, unset=FROM_MODEL),
        'edge_tolerance_m': ParamSpec('edge_tolerance_m', FROM_MODEL, 'distance [m] within which '
                                      'the CoP counts as on a support polygon edge; -1 = the '
                                      'model\'s', 0.0, 0.05, read_only=True, unset=FROM_MODEL),
        'sample_period_s': ParamSpec('sample_period_s', FROM_MODEL, 'nominal period of the '
                                     'measurements [s]; -1 = the model\'s', 1e-4, 0.1,
                                     read_only=True, unset=FROM_MODEL),
        'guard_com_height_m': ParamSpec('guard_com_height_m', FROM_MODEL, 'CoM guard: falling '
                                        'whenever the CoM is below this height [m]; -1 = the '
                                        'model\'s', 0.0, 2.0, read_only=True, unset=FROM_MODEL),
    }
    return tuple(specs[name] for name in names)


def load_model_for(node: Node, model_path: str, requested: Mapping[str, ParamValue],
                   max_bytes: int = DEFAULT_MAX_MODEL_BYTES
                   ) -> tuple[PerModeDecisionLists, ModelMetadata, FeatureSettings]:
    """Load the model named by ``model_path`` ('' = the shipped default) and resolve the
    node's feature-setting parameters against it: ``(lists, metadata, settings)``.

    Raises :class:`NodeStartupError` with one clear reason if the model cannot be used or a
    set parameter differs from the model's setting.
    """
    path = Path(model_path).expanduser() if model_path else default_model_path()
    try:
        lists, metadata = load_model(path, max_bytes)
    except ModelFileError as error:
        raise NodeStartupError(f'no usable model: {error}') from error
    specs = {spec.name: spec for spec in feature_setting_params(list(requested))}
    try:
        settings = metadata.feature_settings.resolve(
            {name: specs[name].value_or_none(value) for name, value in requested.items()},
            what=f'model {path}')
    except FeatureSettingsMismatch as error:
        raise NodeStartupError(f'feature settings differ from the model\'s: {error}') from error
    node.get_logger().info(f'model {path}: feature settings {settings}')
    return lists, metadata, settings


def declare_parameters(node: Node, specs: Sequence[ParamSpec],
                       cross_check: Optional[CrossCheck] = None) -> dict[str, ParamValue]:
    """Declare ``specs`` on ``node`` behind a validating on-set-parameters callback.

    The callback is registered first, so values from a params file or ``-p`` are validated at
    declaration too; any rejection at start-up raises :class:`NodeStartupError` with the
    reason. ``cross_check`` sees the proposed values of every parameter (current values with
    the change applied) once all are declared. Returns the declared values by name.
    """
    by_name = {spec.name: spec for spec in specs}

    def validate(parameters: list[Parameter]) -> SetParametersResult:
        proposed: dict[str, ParamValue] = {}
        for parameter in parameters:
            spec = by_name.get(parameter.name)
            if spec is None:
                continue            # not ours (e.g. use_sim_time): leave it to its owner
            reason = spec.check(parameter.value)
            if reason is not None:
                return SetParametersResult(successful=False, reason=reason)
            proposed[parameter.name] = parameter.value
        if cross_check is not None and all(node.has_parameter(name) for name in by_name):
            merged = {name: node.get_parameter(name).value for name in by_name}
            merged.update(proposed)
            reason = cross_check(merged)
            if reason is not None:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(validate)
    try:
        for spec in specs:
            node.declare_parameter(spec.name, spec.default, spec.descriptor())
    except ParameterException as error:
        raise NodeStartupError(f'invalid parameter: {error}') from error
    values = {spec.name: node.get_parameter(spec.name).value for spec in specs}
    if cross_check is not None:
        reason = cross_check(values)
        if reason is not None:
            raise NodeStartupError(f'invalid parameters: {reason}')
    return values


# --------------------------------------------------------------------------------------------
# Runs (trajectories) in a stream of sample times
# --------------------------------------------------------------------------------------------

class SampleAge:
    """How late a sample arrives: its age [s] when received.

    With ``use_sim_time`` the age is the node's ROS clock (``/clock``) minus the sample time.
    Otherwise the sample times are assumed to advance at the rate of wall time (a robot, a
    replay at 1x), and the age is the arrival delay beyond the least-delayed sample of the
    run: ``(wall - t) - min over the run of (wall - t)`` (the clock offset estimated from the
    freshest samples, as NTP does). :meth:`reset` at every new run.
    """

    def __init__(self, node: Node) -> None:
        self._node = node
        self._sim_time = bool(node.get_parameter('use_sim_time').value)
        self.reset()

    def reset(self) -> None:
        self._min_offset_s = math.inf

    def age_s(self, t: float) -> float:
        if self._sim_time:
            return self._node.get_clock().now().nanoseconds * 1e-9 - t
        offset = time.monotonic() - t
        if offset < self._min_offset_s:
            self._min_offset_s = offset
        return offset - self._min_offset_s


MAX_SAMPLE_AGE = ParamSpec(
    'max_sample_age_s', 0.05, 'a sample older than this when received [s] is counted and '
    'reported stale instead of being used (0 = no age check); see SampleAge', 0.0, 10.0)


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
    [s] (simulation time, like every stamp of the package), from ``sample_time()``. The value
    ``unmatched_inputs`` lists the topics of ``inputs`` no publisher is matched with yet
    (empty when every input is connected): a run should start only once it is empty
    everywhere, or its first samples are lost for the unmatched subscriber.
    """

    def __init__(self, node: Node, report: Callable[[], Report],
                 sample_time: Callable[[], float], inputs: Sequence[Subscription] = (),
                 errors: Optional['InputErrors'] = None,
                 period_s: float = 1.0 / DIAGNOSTICS_RATE_HZ) -> None:
        self._node = node
        self._errors = errors
        self._report = report
        self._sample_time = sample_time
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
        msg.header.stamp = ros_qos.stamp(max(0.0, self._sample_time()))
        self._publisher.publish(msg)


class InputErrors:
    """Counts rejected inputs and logs them, throttled to one line per ``throttle_s``."""

    def __init__(self, node: Node, throttle_s: float = 1.0) -> None:
        self._node = node
        self._throttle_s = throttle_s
        self.count = 0
        self.last: str = ''
        self._reported = 0

    def reject(self, what: str, error: Exception) -> None:
        self.count += 1
        self.last = f'{what}: {error}'
        self._node.get_logger().warning(
            f'dropped {self.last} ({self.count} dropped so far)',
            throttle_duration_sec=self._throttle_s)

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


# --------------------------------------------------------------------------------------------
# main()
# --------------------------------------------------------------------------------------------

def run_node(factory: Callable[[], Node], name: str, args: Optional[list[str]] = None) -> int:
    """Create the node with ``factory`` and spin it until Ctrl-C / SIGTERM / shutdown.

    Returns the process exit code: 0 after a normal shutdown, 1 if the node could not start
    (the reason is logged as one FATAL line, no traceback).
    """
    return run_nodes((factory,), name, args)


def run_nodes(factories: Sequence[Callable[[], Node]], name: str,
              args: Optional[list[str]] = None) -> int:
    """Create one node per factory in this process and spin them all with one
    SingleThreadedExecutor (the callbacks of all nodes run in turn, no threads), until
    Ctrl-C / SIGTERM / shutdown. Exit code as :func:`run_node`; if one node cannot start,
    none runs."""
    rclpy.init(args=args)
    nodes: list[Node] = []
    try:
        try:
            for factory in factories:
                nodes.append(factory())
        except NodeStartupError as error:
            rclpy.logging.get_logger(name).fatal(f'cannot start: {error}')
            return 1
        executor = SingleThreadedExecutor()
        for node in nodes:
            executor.add_node(node)
        try:
            executor.spin()
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        except Exception:
            # Ctrl-C / SIGTERM invalidate the context at once, in C; a callback that was already
            # running then fails on its next publish ("publisher's context is invalid"). That is
            # the shutdown, not a fault; with the context still valid it is one.
            if rclpy.ok():
                raise
        return 0
    finally:
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()


def spin_until(executor: Executor, done: Callable[[], bool], timeout_s: float,
               check: Callable[[], None] = lambda: None) -> bool:
    """Spin ``executor`` until ``done()`` or ``timeout_s`` wall seconds; ``check()`` may raise.

    Returns whether ``done()`` became true.
    """
    deadline = time.monotonic() + timeout_s
    while not done():
        check()
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return False
        executor.spin_once(timeout_sec=min(0.05, remaining))
    return True
