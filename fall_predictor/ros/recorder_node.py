"""recorder_node: the live topics into rosbag2 (MCAP) bags, one bag per run, losing nothing.

Subscribes (QoS of :mod:`fall_predictor.contract.wire`) to the measurement, features, state,
joint states, joint commands, push and controller mode topics, and writes them with
:class:`~fall_predictor.data.bag_writer.BagWriter`: same topics, types, QoS metadata and log times
(the stamps: simulation time from the simulator, ROS time on a robot) as the generated datasets,
so a recorded bag is read by
:func:`~fall_predictor.data.bagio.read_trajectory` and the dataset/training code like a generated
one.

One recording per run: ``<bag_path>/run_000``, ``run_001``, ..., each written as parts of at
most ``split_duration_s`` of sample time (``run_000/part_000``, ``part_001``, ...; each part a
complete rosbag2 bag once closed), so a recorder that is killed loses only its open part, and
that only until ``fall-predictor repair-bag`` recovers it; the package's reader
(:func:`~fall_predictor.data.bagio.read_trajectory`) reads a run's parts as one recording.
Next to the parts, ``fall_predictor.json`` (written when the run starts and at every part
change, atomically) records the parts, the messages written and the samples missing per topic.

**Gaps.** For every 1 kHz stamped stream the recorder counts the sample times missing on the
1 ms grid (lost by DDS or never published), and DDS's own message-lost events; both are in
``/diagnostics`` (WARN while they grow: never OK while losing data) and in the run's
``fall_predictor.json``.

A run ends when sample time goes
back to the start (a simulator ``~/reset``); each stamped topic is split on its own time line,
so messages of the old run still in flight go to the old bag, which is closed once every
stamped topic has moved on. A message that is merely out of order (a stray publisher) stays in
the current run. Pushes and controller-mode changes go to the run of the latest
measurement; a controller mode (no stamp) is logged at that measurement's time.

Nothing is lost between reception and disk: the subscription callbacks only queue the
serialized bytes (raw subscriptions, no deserialization in the executor); a writer thread
decodes, validates and writes them; on shutdown the subscriptions are closed first, then the
queue is drained and every bag closed. A message that breaks the wire contract is rejected
(logged, counted) so that the bags stay readable. Counts of received, written and rejected
messages per topic are in ``/diagnostics`` and logged at shutdown. Start the recorder, and
wait for its ``unmatched_inputs`` to be empty, before starting a run: DDS delivers nothing
published before a subscription is matched.
"""
from __future__ import annotations

import json
import queue
import threading
import traceback
from collections.abc import Callable
from contextlib import ExitStack
from datetime import datetime, timezone
from pathlib import Path
from typing import Optional

import rclpy
from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, String

from fall_predictor.data import bagio
from fall_predictor.data.bag_writer import BagWriter
from fall_predictor.monitor.fileio import atomic_write_text
from fall_predictor.data.sample_order import RunTracker, Sample
from fall_predictor.ros.endpoints import create_subscription
from fall_predictor.ros.health import Diagnostics, InputErrors, Report
from fall_predictor.ros.parameters import NodeStartupError, ParamSpec, declare_parameters
from fall_predictor.ros.runner import run_node
from fall_predictor.contract import messages
from fall_predictor.msg import FallEvent, FallState, Features, Measurement
from fall_predictor.contract.topics import (CONTROLLER_MODE, FALL_DIRECTION, FALL_EVENT, FALLING, FEATURES,
                                        JOINT_COMMANDS, JOINT_STATES, MEASUREMENT, PUSH, STATE,
                                        TopicSpec, WireFormatError, check_controller_mode)
from fall_predictor.contract.wire import LEVEL_OK, LEVEL_WARN, JointStateSample
from fall_predictor.contract.topics import ns_to_time, stamp_to_ns

NODE_NAME = 'recorder_node'
#: Recorded topics and their rclpy message classes.
RECORDED: tuple[tuple[TopicSpec, type], ...] = (
    (MEASUREMENT, Measurement), (FEATURES, Features), (STATE, FallState),
    (JOINT_STATES, JointState), (JOINT_COMMANDS, JointState), (PUSH, WrenchStamped),
    (CONTROLLER_MODE, String), (FALLING, Bool), (FALL_DIRECTION, Vector3Stamped),
    (FALL_EVENT, FallEvent),
)
#: Stamped streams split into runs on their own time line; the value says whether a new
#: t = 0 sample starts a run (not for states: degraded states repeat the last sample time).
_RUN_SPLIT: dict[str, bool] = {MEASUREMENT.name: True, FEATURES.name: True, STATE.name: False,
                               JOINT_STATES.name: True, JOINT_COMMANDS.name: True}
#: A jump back in time starts a run only if it lands before this time [s]: runs start at
#: t = 0, and the first sample of every stamped stream is within milliseconds of it; a
#: smaller jump back (a stray message from another publisher) stays in the current run.
_RUN_START_WINDOW_S = 1.0
#: Queue length above which /diagnostics warns that the writer falls behind.
_BACKLOG_WARN = 1000

#: Stamped 1 kHz streams whose gaps are counted, with their sample period [s].
_GAP_PERIOD_S: dict[str, float] = {MEASUREMENT.name: 1e-3, FEATURES.name: 1e-3,
                                   STATE.name: 1e-3, JOINT_COMMANDS.name: 1e-3}
#: The run's record next to its parts.
RUN_RECORD = 'fall_predictor.json'

PARAMS = (
    ParamSpec('bag_path', '', 'directory receiving one recording per run (run_000, run_001, '
              '...); empty = ./fall_predictor_<UTC time>', read_only=True),
    ParamSpec('split_duration_s', 10.0, 'each run is written as parts of at most this much '
              'sample time [s]: a killed recorder loses at most its open part; 0 = one part',
              0.0, 86400.0, read_only=True),
)


def _stamp_ns(topic: str, msg: bagio.RosbagsMsg) -> Optional[int]:
    """Validate a deserialized message against the wire contract and return its header stamp
    [ns] as it was sent (None for the unstamped topics, logged at the latest measurement's);
    raises WireFormatError.

    Stamps are kept whatever clock made them: simulation time from the simulator, ROS time
    (seconds since 1970, beyond the simulation-time range of the package's records) on a robot,
    where its drivers stamp ``/joint_states`` and the monitor's outputs keep their samples' stamps."""
    if topic == CONTROLLER_MODE.name:
        check_controller_mode(msg.data)
        return None
    if topic == FALLING.name:
        if not isinstance(msg.data, bool):
            raise WireFormatError(f'falling must be a bool, got {msg.data!r}')
        return None
    if topic in (FALL_EVENT.name, FALL_DIRECTION.name):
        return None                         # logged at the latest measurement's time
    stamp_ns = stamp_to_ns(msg.header.stamp.sec, msg.header.stamp.nanosec)
    if topic == MEASUREMENT.name:             # a measurement that carries a fault is recorded too
        messages.measurement_from_msg(msg)
    elif topic == FEATURES.name:
        messages.features_from_msg(msg)
    elif topic == STATE.name:
        messages.fall_state_from_msg(msg)
    elif topic in (JOINT_STATES.name, JOINT_COMMANDS.name):
        JointStateSample(ns_to_time(stamp_ns), tuple(msg.name), msg.position, msg.velocity, msg.effort)
    else:
        bagio.decode(bagio.BagMessage(topic, '', 0, msg))       # the simulator's push
    return stamp_ns


class RecorderNode(Node):
    """Records the live topics; see the module documentation."""

    def __init__(self, **kwargs: object) -> None:
        super().__init__(NODE_NAME, **kwargs)
        p = declare_parameters(self, PARAMS)
        stamp = datetime.now(timezone.utc).strftime('%Y%m%d_%H%M%S')
        self.bag_dir = Path(str(p['bag_path']) or f'fall_predictor_{stamp}').expanduser()
        try:
            self.bag_dir.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise NodeStartupError(f'cannot create bag_path {self.bag_dir}: {error}') from error
        if any(self.bag_dir.glob('run_*')):
            raise NodeStartupError(f'bag_path {self.bag_dir} already holds recordings (run_*)')

        names = [spec.name for spec, _ in RECORDED]
        #: Per topic: messages received, written to a bag, rejected as malformed.
        self.received = dict.fromkeys(names, 0)
        self.written = dict.fromkeys(names, 0)
        self.rejected = dict.fromkeys(names, 0)
        #: Bags written so far (closed or open), by run index.
        self.bags: dict[int, Path] = {}
        self._invalid = InputErrors(self)
        self._queue: queue.SimpleQueue[Optional[tuple[str, bytes]]] = queue.SimpleQueue()
        self._trackers = {name: RunTracker(restart, _RUN_START_WINDOW_S)
                          for name, restart in _RUN_SPLIT.items()}
        self._topic_run = dict.fromkeys(_RUN_SPLIT, 0)
        self._seen: set[str] = set()
        #: Open part of each run: (part index, first log time [ns], exit stack, writer).
        self._open: dict[int, tuple[int, int, ExitStack, BagWriter]] = {}
        self._parts: dict[int, list[str]] = {}
        self._split_ns = round(float(p['split_duration_s']) * 1e9)
        #: Samples missing on the 1 ms grid: per topic in total, and per run and topic.
        self.missing = dict.fromkeys(_GAP_PERIOD_S, 0)
        self._run_missing: dict[int, dict[str, int]] = {}
        self._latest_t: dict[str, float] = {}   # latest sample time per topic in its run
        self._run_written: dict[int, dict[str, int]] = {}
        self.messages_lost = 0              # DDS message-lost events (count of messages)
        self._lost_at_report = 0
        self._missing_at_report = 0
        self._measurement_t_ns = 0
        self._write_errors = 0
        self._types = {spec.name: spec.msg_type for spec, _ in RECORDED}

        self._inputs = [
            create_subscription(self, msg_class, spec, self._queue_callback(spec.name), raw=True,
                                lossless=True, on_message_lost=self._on_message_lost)
            for spec, msg_class in RECORDED]
        self._writer = threading.Thread(target=self._write_loop, name='bag_writer', daemon=True)
        self._writer.start()
        self._diagnostics = Diagnostics(self, self._report, lambda: self._measurement_t_ns / 1e9,
                                        self._inputs)
        self.get_logger().info(f'recording {len(RECORDED)} topics into {self.bag_dir}')

    def _queue_callback(self, topic: str) -> Callable[[bytes], None]:
        def on_message(raw: bytes) -> None:
            self.received[topic] += 1
            self._queue.put((topic, raw))
        return on_message

    # -- writer thread ---------------------------------------------------------------------
    def _write_loop(self) -> None:
        while (item := self._queue.get()) is not None:
            try:
                self._write(*item)
            except Exception:  # noqa: BLE001 - keep recording the other messages
                self._write_errors += 1
                self.get_logger().error(f'cannot record a {item[0]} message:\n'
                                        f'{traceback.format_exc()}', throttle_duration_sec=1.0)

    def _write(self, topic: str, raw: bytes) -> None:
        """Decode, validate, find the run of one message and write it to that run's bag."""
        msg_type = self._types[topic]
        try:
            msg = bagio.deserialize_cdr(raw, msg_type)
            stamp_ns = _stamp_ns(topic, msg)
        except Exception as error:  # noqa: BLE001 - whatever does not decode is rejected
            self.rejected[topic] += 1
            self._invalid.reject(topic, error)
            return
        if topic in self._trackers:
            assert stamp_ns is not None
            t = stamp_ns / 1e9
            kind = self._trackers[topic].classify(t)
            if kind is Sample.NEW_RUN:
                self._topic_run[topic] += 1
                self._latest_t.pop(topic, None)
            run = self._topic_run[topic]
            latest = self._latest_t.get(topic)
            if topic in _GAP_PERIOD_S and stamp_ns > 0 and (latest is None or t > latest):
                # Gaps against the latest sample time of the run, so that a stray old stamp
                # (written, but out of order) does not count the samples after it as missing.
                # A state stamped 0 answers no sample (the predictor's staleness report before
                # its first input): on a robot's clock the next one would count 1.8e12 missing.
                period = _GAP_PERIOD_S[topic]
                gap = 0 if latest is None else max(0, round((t - latest) / period) - 1)
                self._latest_t[topic] = t
                if gap:
                    self.missing[topic] += gap
                    run_missing = self._run_missing.setdefault(run, {})
                    run_missing[topic] = run_missing.get(topic, 0) + gap
            self._seen.add(topic)
            t_ns = stamp_ns
            if topic == MEASUREMENT.name:
                self._measurement_t_ns = t_ns
        else:
            run = self._topic_run[MEASUREMENT.name]
            t_ns = self._measurement_t_ns if stamp_ns is None else stamp_ns
        try:
            self._bag(run, t_ns).write(topic, msg_type, t_ns, msg)
        except bagio.BagError as error:
            self._write_errors += 1
            self.get_logger().error(str(error), throttle_duration_sec=1.0)
            return
        self.written[topic] += 1
        run_written = self._run_written.setdefault(run, {})
        run_written[topic] = run_written.get(topic, 0) + 1
        self._close_finished_runs()

    def _bag(self, run: int, t_ns: int) -> BagWriter:
        """The open part of ``run`` for a message at ``t_ns``; a new part once the open one
        spans ``split_duration_s``."""
        current = self._open.get(run)
        if current is not None and self._split_ns and t_ns >= current[1] + self._split_ns:
            self._close(run, finished=False)
            current = None
        if current is None:
            path = self.bag_dir / f'run_{run:03d}'
            parts = self._parts.setdefault(run, [])
            part = path / f'part_{len(parts):03d}'
            stack = ExitStack()
            self._open[run] = (len(parts), t_ns, stack, stack.enter_context(BagWriter(part)))
            parts.append(part.name)
            self.bags[run] = path
            self._write_run_record(run, complete=False)
            self.get_logger().info(f'new bag {part}')
        return self._open[run][3]

    def _write_run_record(self, run: int, complete: bool) -> None:
        """The run's ``fall_predictor.json``: parts, messages written, samples missing."""
        record = {'parts': self._parts.get(run, []), 'complete': complete,
                  'written': self._run_written.get(run, {}),
                  'missing_samples': self._run_missing.get(run, {}),
                  'dds_messages_lost_so_far': self.messages_lost}
        atomic_write_text(self.bag_dir / f'run_{run:03d}' / RUN_RECORD,
                          json.dumps(record, indent=1, sort_keys=True) + '\n')

    def _on_message_lost(self, info: object) -> None:
        self.messages_lost += int(getattr(info, 'total_count_change', 1) or 1)

    def _close_finished_runs(self) -> None:
        """Close the bags of runs every stamped topic seen so far has left."""
        if not self._seen:
            return
        oldest_active = min(self._topic_run[topic] for topic in self._seen)
        for run in [r for r in self._open if r < oldest_active]:
            self._close(run)

    def _close(self, run: int, finished: bool = True) -> None:
        """Close the open part of ``run`` (and, when ``finished``, mark the run complete)."""
        _, _, stack, _ = self._open.pop(run)
        try:
            stack.close()
        except bagio.BagError as error:
            self._write_errors += 1
            self.get_logger().error(str(error))
        self._write_run_record(run, complete=finished)

    # -- health and shutdown ---------------------------------------------------------------
    def summary(self) -> dict[str, object]:
        """Counts per topic and the bags; ``unaccounted`` counts messages received but neither
        written, rejected nor still queued (lost to write errors): 0 when nothing was lost."""
        queued = self._queue.qsize()
        unaccounted = (sum(self.received.values()) - sum(self.written.values())
                       - sum(self.rejected.values()) - queued)
        return {'bag_dir': str(self.bag_dir), 'bags': [str(p) for p in self.bags.values()],
                'received': dict(self.received), 'written': dict(self.written),
                'rejected': dict(self.rejected), 'write_errors': self._write_errors,
                'queued': queued, 'unaccounted': unaccounted,
                'missing_samples': dict(self.missing), 'dds_messages_lost': self.messages_lost}

    def _report(self) -> Report:
        summary = self.summary()
        values = {'bag_dir': summary['bag_dir'], 'open_bags': len(self._open),
                  'queued': summary['queued'], 'write_errors': self._write_errors,
                  'unaccounted': summary['unaccounted'], 'last_error': self._invalid.last}
        for topic in self.received:
            values[f'{topic} received/written/rejected'] = (
                f'{self.received[topic]}/{self.written[topic]}/{self.rejected[topic]}')
        values['missing_samples'] = sum(self.missing.values())
        values['dds_messages_lost'] = self.messages_lost
        for topic, count in self.missing.items():
            values[f'{topic} missing'] = count
        rejected = self._invalid.new_since_last_call()
        missing = sum(self.missing.values()) - self._missing_at_report
        self._missing_at_report += missing
        lost = self.messages_lost - self._lost_at_report
        self._lost_at_report += lost
        if (self._write_errors or rejected or missing or lost
                or self._queue.qsize() > _BACKLOG_WARN):
            message = (f'{rejected} rejected, {missing} samples missing, {lost} lost by DDS, '
                       f'{self._write_errors} write errors, {self._queue.qsize()} queued')
            return LEVEL_WARN, message, values
        return LEVEL_OK, 'recording', values

    def destroy_node(self) -> None:
        """Stop receiving, write everything queued, close every bag, log the counts."""
        for subscription in self._inputs:
            self.destroy_subscription(subscription)
        self._queue.put(None)
        self._writer.join()
        for run in list(self._open):
            self._close(run)
        # After Ctrl-C the context is already shut down: log without the node's /rosout.
        rclpy.logging.get_logger(f'{NODE_NAME}.shutdown').info(
            f'recording finished: {json.dumps(self.summary())}')
        super().destroy_node()


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.recorder_node --ros-args ...``."""
    return run_node(RecorderNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
