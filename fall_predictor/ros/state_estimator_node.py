"""state_estimator_node: the robot's sensor topics -> the measurement the feature node reads.

Subscribes to ``/robot_description`` (the URDF with ``l_sole`` / ``r_sole`` frames, transient
local), ``/joint_states``, ``/imu/data``, ``/left_foot/wrench`` and ``/right_foot/wrench``
(:data:`fall_predictor.data.topics.SENSOR_TOPICS`); groups the messages by header stamp, and
for each complete sample runs :class:`~fall_predictor.monitor.estimator.StateEstimator` (the
same class the offline ``estimation-error`` runs over bags) and publishes
``/fall_predictor/measurement`` (layout v1). A stamp still missing a message when
``max_pending_samples`` newer stamps wait is processed without it (a missing foot sensor makes
that foot unloaded) or, without joints or IMU, dropped.

Bad input never stops the node: a URDF the estimator cannot use is logged and the node waits
for another; samples the estimator rejects (NaN, out-of-order or stale stamps, unknown joints)
are logged (throttled), counted and dropped; numeric failures are caught the same way. Sample
order as in the monitor nodes (:class:`~fall_predictor.data.sample_order.SampleIntake`): a
new run by ``~/reset`` (std_srvs/Trigger) or the restart rule, never by one old stamp. Health
goes to ``/diagnostics``: OK, WARN when samples were dropped, missing or degraded in the last
period, STALE when no description or no sample arrived for ``stale_timeout_s`` of wall time.
"""
from __future__ import annotations

import time
from typing import Optional

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import Trigger

from fall_predictor.data.sample_order import Sample, SampleIntake
from fall_predictor.data.topics import (IMU, LEFT_FOOT_WRENCH, MEASUREMENT, RIGHT_FOOT_WRENCH,
                                        ROBOT_DESCRIPTION, SENSOR_JOINT_STATES)
from fall_predictor.data.wire import LEVEL_OK, LEVEL_STALE, LEVEL_WARN
from fall_predictor.monitor.estimator import EstimatorConfig, SensorSample, StateEstimator
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.common import (HANDLED_ERRORS, SAMPLE_PERIOD_S, Diagnostics, InputErrors,
                                       ParamSpec, Report, create_publisher, create_subscription,
                                       declare_parameters, guarded, run_node)
from fall_predictor.ros.in_process import Output
from fall_predictor.ros.sensor_conversions import imu_from_msg, stamp_ns, wrench_from_msg

NODE_NAME = 'state_estimator_node'
PARAMS = (
    ParamSpec('contact_force_n', EstimatorConfig().contact_force_n,
              'F/T normal force above which a foot is loaded [N]', 0.0, 10000.0, read_only=True),
    ParamSpec('max_pending_samples', 5, 'newer stamps waiting before a sample missing a message '
              'is processed without it', 1, 1000, read_only=True),
    ParamSpec('stale_timeout_s', 0.5, 'wall time [s] without a sample after which /diagnostics '
              'reports STALE', 0.01, 60.0),
)
_PARTS = ('joints', 'imu', 'left', 'right')


class StateEstimatorNode(Node):
    """Wraps :class:`~fall_predictor.monitor.estimator.StateEstimator`; see the module docs."""

    def __init__(self, **kwargs: object) -> None:
        super().__init__(NODE_NAME, **kwargs)
        p = declare_parameters(self, PARAMS)
        self._config = EstimatorConfig(contact_force_n=float(p['contact_force_n']))
        self._max_pending = int(p['max_pending_samples'])
        self._stale_timeout_s = float(p['stale_timeout_s'])
        self._estimator: Optional[StateEstimator] = None
        self._pending: dict[int, dict] = {}
        self._runs = SampleIntake(SAMPLE_PERIOD_S)
        self._bad_inputs = InputErrors(self)
        self.counts = {'samples': 0, 'measurements': 0, 'rejected': 0, 'degraded': 0, 'incomplete': 0,
                       'resets': 0}
        self._missing_at_report = 0
        self._last_input_wall: Optional[float] = None
        #: The measurements, published and handed to in-process consumers (``fall_monitor``).
        self.output = Output(create_publisher(self, Float64MultiArray, MEASUREMENT))
        inputs = [
            create_subscription(self, String, ROBOT_DESCRIPTION, self._on_description),
            create_subscription(self, JointState, SENSOR_JOINT_STATES,
                                lambda m: self._on_part('joints', m, (tuple(m.name), m.position, m.velocity))),
            create_subscription(self, Imu, IMU, lambda m: self._on_part('imu', m, imu_from_msg(m))),
            create_subscription(self, WrenchStamped, LEFT_FOOT_WRENCH,
                                lambda m: self._on_part('left', m, wrench_from_msg(m))),
            create_subscription(self, WrenchStamped, RIGHT_FOOT_WRENCH,
                                lambda m: self._on_part('right', m, wrench_from_msg(m))),
        ]
        self.create_service(Trigger, '~/reset', self._on_reset)
        self._diagnostics = Diagnostics(self, self._report, lambda: self._runs.last_t or 0.0, inputs,
                                        self._bad_inputs)
        self.get_logger().info('state estimator waiting for /robot_description')

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        self._runs.reset()
        self._pending.clear()
        if self._estimator is not None:
            self._estimator.reset()
        self.counts['resets'] += 1
        response.success, response.message = True, 'estimator reset; next sample starts a run'
        return response

    @guarded('robot description')
    def _on_description(self, msg: String) -> None:
        try:
            self._estimator = StateEstimator(msg.data, self._config)
        except HANDLED_ERRORS as error:
            self._bad_inputs.reject('robot description', error)
            return
        self._pending.clear()
        self.get_logger().info(f'robot description: {self._estimator.total_mass_kg:.2f} kg, '
                               f'{self._estimator.model.nv - 6} joints')

    @guarded('sensor sample')
    def _on_part(self, part: str, msg, value) -> None:
        self._last_input_wall = time.monotonic()
        if self._estimator is None:
            return
        self._pending.setdefault(stamp_ns(msg), {})[part] = value
        self._flush()

    def _flush(self) -> None:
        for ns in sorted(self._pending):
            parts = self._pending[ns]
            complete = len(parts) == len(_PARTS)
            if not complete and len(self._pending) <= self._max_pending:
                return
            del self._pending[ns]
            if 'joints' not in parts or 'imu' not in parts:
                self.counts['incomplete'] += 1
                continue
            self._process(ns, parts)

    def _process(self, ns: int, parts: dict) -> None:
        assert self._estimator is not None
        t = ns / 1e9
        kind = self._runs.classify(t)
        if kind is Sample.NEW_RUN:
            self._estimator.reset()
        elif kind is not Sample.NEXT:
            return                          # duplicate, out of order: counted by the intake
        names, q, dq = parts['joints']
        quat, gyro, acc = parts['imu']
        sample = SensorSample(t=t, joint_names=names, q=q, dq=dq, imu_quat_xyzw=quat, gyro_rad_s=gyro,
                              accel_m_s2=acc, left_wrench=parts.get('left'), right_wrench=parts.get('right'))
        self.counts['samples'] += 1
        try:
            rejected_before = self._estimator.n_rejected
            m = self._estimator.update(sample)
            if m is None:        # rejected, or no loaded sole has anchored the base yet
                if self._estimator.n_rejected > rejected_before:
                    self.counts['rejected'] += 1
                    self._bad_inputs.reject(f'sample at t = {t} s', ValueError(self._estimator.last_issue))
                return
            self.counts['degraded'] += bool(self._estimator.degraded)
            self.output.publish(ros_qos.measurement_to_msg(m))
        except HANDLED_ERRORS as error:
            self._bad_inputs.reject(f'sample at t = {t} s', error)
            return
        self.counts['measurements'] += 1

    def _report(self) -> Report:
        values = {'t_s': self._runs.last_t, 'invalid_inputs': self._bad_inputs.count,
                  'last_error': self._bad_inputs.last, **self._runs.counters(), **self.counts}
        dropped = self._bad_inputs.new_since_last_call()
        missing = self._runs.missing - self._missing_at_report
        self._missing_at_report = self._runs.missing
        if self._estimator is None:
            return LEVEL_STALE, 'no usable /robot_description yet', values
        if self._last_input_wall is None:
            return LEVEL_STALE, 'no sensor sample received yet', values
        silent_s = time.monotonic() - self._last_input_wall
        if silent_s > self._stale_timeout_s:
            return LEVEL_STALE, f'no sensor sample for {silent_s:.1f} s', values
        if dropped or missing:
            return LEVEL_WARN, f'{dropped} samples dropped, {missing} samples missing', values
        return LEVEL_OK, 'running', values


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.state_estimator_node --ros-args ...``."""
    return run_node(StateEstimatorNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
