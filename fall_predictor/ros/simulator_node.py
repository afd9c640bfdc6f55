"""simulator_node: the simulated humanoid (PyBullet, 1 ms steps), lock-stepped with the controller.

Publishes, all stamped with simulation time:

* ``/fall_predictor/measurement`` and ``/clock`` every physics step (1 kHz of simulation time);
* ``/joint_states`` at ``joint_state_rate_hz`` of simulation time;
* ``/fall_predictor/push`` once per applied push (onset stamp, world force);
* ``/diagnostics`` once per wall second.

With ``publish_sensors`` the node publishes what a robot publishes instead: ``/joint_states``
(with efforts), ``/imu/data``, ``/left_foot/wrench`` and ``/right_foot/wrench`` from the sensor
model of :mod:`fall_predictor.sim.sensors` (noise x ``sensor_noise_scale``, seeded by
``sensor_seed`` and the world count), each stream at its own rate and stamp offset as a robot's
drivers publish them (``sensor_joint_rate_hz``, ``sensor_imu_offset_s``, ...; joint states split
into legs and upper body with ``sensor_split_joints``, :mod:`fall_predictor.sim.drivers`),
``/robot_description`` once (transient local), and its exact state on
``/fall_predictor/ground_truth`` (evaluation only): ``/fall_predictor/measurement`` is then the
state_estimator_node's. Every stamp is simulation time, the time of ``/clock``: the other nodes
run with ``use_sim_time``.

Subscribes to ``/fall_predictor/joint_commands`` (the controller node's joint targets) and to
``/fall_predictor/push_request`` (see :data:`~fall_predictor.ros.health.PUSH_REQUEST`).

**Lock-step** (``lockstep``, default true): after publishing sample k the node waits for the
joint command stamped with sample k's time, applies it and steps, so the robot obeys the
controller exactly and a run is deterministic. If no matching command arrives within
``command_timeout_s`` of wall time, it steps with the last command and counts a missed
command (reported in ``/diagnostics``). Without lock-step, a wall-clock timer steps the world
at ``real_time_factor`` with the latest command received. A run starts (sample t = 0 is
published) only once the measurement has a subscriber and, in lock-step, the command topic a
publisher; other late subscribers miss the first samples. For a complete record from t = 0,
set ``autostart`` false and call ``~/reset`` once every node's ``/diagnostics`` reports empty
``unmatched_inputs``, as the bring-up does.

**Pacing**: ``real_time_factor`` 1.0 keeps simulation time from running ahead of wall time;
0 steps as fast as the controller answers (lock-step only). A pipeline slower than real time
simply runs slower (the achieved factor is in ``/diagnostics``).

**Pushes** (method §3): a constant horizontal force for 0.1 s on the torso. A push request gives
the onset (header stamp, simulation time; a past time means the next step), the force in the
robot's heading frame and its torque about the CoM, ``(0, 0, h) x F``, from which the
application height ``h`` above the CoM is recovered. With ``random_push_period_s`` > 0 the node
also pushes by itself every period of simulation time, drawing force, direction and height
from :class:`~fall_predictor.sim.pushes.PushDistribution` seeded with ``random_push_seed``. A
request while a push is still acting is rejected (logged and counted).

**Fallen**: with ``stop_when_fallen`` the world stops stepping at the first fallen sample
(method §4); otherwise it keeps going. ``~/reset`` (std_srvs/Trigger) starts a fresh world at
t = 0 (the other nodes notice time going backwards and reset themselves); ``~/pause``
(std_srvs/SetBool) holds the world (true) or lets it go on (false).
"""
from __future__ import annotations

import math
import time
from functools import partial
from collections.abc import Mapping
from dataclasses import replace
from typing import Optional

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import SetBool, Trigger

from fall_predictor.profiles import DEFAULT_ROBOT, RobotProfile
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.robot.controllers import BalanceController, controller_configs
from fall_predictor.ros.robots import ROBOT_PARAM, profile_for
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.health import Diagnostics, InputErrors, Report, steady_clock
from fall_predictor.ros.parameters import (NodeStartupError, ParamSpec, ParamValue, declare_parameters)
from fall_predictor.ros.runner import run_node
from fall_predictor.ros.in_process import Output, take_from
from fall_predictor.sim.pushes import PushDistribution
from fall_predictor.monitor.records import Measurement, PushSpec
from fall_predictor.sim.simulator import DT_S, Simulator
from fall_predictor.ros.simulated_sensors import SimulatedSensors
from fall_predictor.contract import messages
from fall_predictor.contract.topics import (CLOCK, GROUND_TRUTH, JOINT_COMMANDS, JOINT_STATES,
                                            MEASUREMENT, ODOM_FRAME, PUSH, PUSH_REQUEST, SIM_RATE_HZ,
                                            WireFormatError)
from fall_predictor.msg import Measurement as MeasurementMsg
from fall_predictor.sim.drivers import DriverTiming
from fall_predictor.contract.wire import LEVEL_OK, LEVEL_WARN

NODE_NAME = 'simulator_node'
#: Period of the wall-clock check for a run start and for lock-step command timeouts [s].
_WATCHDOG_PERIOD_S = 0.01
#: Lock-step pacing gives up catching up with wall time when this far behind [s].
_MAX_PACING_LAG_S = 0.1
_PAUSED = 'paused (~/pause)'
#: Lock-step with an in-process controller: steps per executor wake-up (see ``_advance``).
_STEPS_PER_WAKEUP = 5

PARAMS = (
    ROBOT_PARAM,
    ParamSpec('lockstep', True, 'wait for the controller command of each sample before '
              'stepping (deterministic runs); false: step on a wall-clock timer', read_only=True),
    ParamSpec('real_time_factor', 1.0, 'simulated seconds per wall second (upper bound); '
              '0 = as fast as possible (lock-step only)', 0.0, 100.0),
    ParamSpec('command_timeout_s', 0.5, 'lock-step: wall time [s] to wait for the command of a '
              'sample before stepping with the last command (a missed command)', 0.001, 60.0),
    ParamSpec('joint_state_rate_hz', 100.0, 'rate of /joint_states in simulation time [Hz], '
              'rounded to a whole number of 1 ms steps', 1.0, SIM_RATE_HZ, read_only=True),
    ParamSpec('stop_when_fallen', False, 'stop stepping at the first fallen sample (until '
              '~/reset); false: keep simulating the fallen robot'),
    ParamSpec('autostart', True, 'start a run at launch; false: wait for the first ~/reset',
              read_only=True),
    ParamSpec('random_push_period_s', 0.0, 'push the robot every this many simulated seconds '
              'with a push drawn from the method §3 distribution; 0 = off', 0.0, 3600.0,
              read_only=True),
    ParamSpec('random_push_seed', 0, 'seed of the random pushes', 0, 2**31 - 1,
              read_only=True),
    ParamSpec('publish_sensors', False, 'publish the robot sensor topics and the exact state on '
              '/fall_predictor/ground_truth (the measurement comes from state_estimator_node)',
              read_only=True),
    ParamSpec('sensor_noise_scale', 1.0, 'multiplier of every sensor noise and bias (0 = ideal)',
              0.0, 100.0, read_only=True),
    ParamSpec('sensor_seed', 0, 'seed of the sensor noise', 0, 2**31 - 1, read_only=True),
    ParamSpec('sensor_joint_rate_hz', 1000.0, 'rate of the sensors\' /joint_states [Hz]', 1.0,
              1000.0, read_only=True),
    ParamSpec('sensor_imu_rate_hz', 1000.0, 'rate of /imu/data [Hz]', 1.0, 1000.0, read_only=True),
    ParamSpec('sensor_wrench_rate_hz', 1000.0, 'rate of the foot wrenches [Hz]', 1.0, 1000.0,
              read_only=True),
    ParamSpec('sensor_imu_offset_s', 0.0, 'IMU stamps this much after the encoders\' [s]', 0.0,
              0.00099, read_only=True),
    ParamSpec('sensor_wrench_offset_s', 0.0, 'foot wrench stamps this much after the encoders\' '
              '[s]', 0.0, 0.00099, read_only=True),
    ParamSpec('sensor_split_joints', False, 'publish the joint states as two messages (legs, upper '
              'body), as two controllers would', read_only=True),
)


def _driver_timing(p: Mapping[str, ParamValue], profile: RobotProfile) -> DriverTiming:
    """How the simulated robot's drivers publish its sensors (the ``sensor_*`` parameters)."""
    groups = profile.legs_and_upper_body() if p['sensor_split_joints'] else ()
    return DriverTiming(joint_rate_hz=float(p['sensor_joint_rate_hz']),
                        imu_rate_hz=float(p['sensor_imu_rate_hz']),
                        wrench_rate_hz=float(p['sensor_wrench_rate_hz']),
                        imu_offset_s=float(p['sensor_imu_offset_s']),
                        wrench_offset_s=float(p['sensor_wrench_offset_s']), joint_groups=groups)


def _check_pacing(values: Mapping[str, ParamValue]) -> Optional[str]:
    if not values['lockstep'] and values['real_time_factor'] == 0.0:
        return 'real_time_factor must be > 0 without lockstep (a timer steps the world)'
    return None


class SimulatorNode(Node):
    """Owns one :class:`~fall_predictor.sim.simulator.Simulator`; see the module documentation."""

    def __init__(self, in_process_controller: bool = False, **kwargs: object) -> None:
        """``in_process_controller``: the joint commands come from a controller node of the same
        process (:meth:`connect_controller`, ``simulated_robot``), not from a subscription;
        ``kwargs`` go to ``Node``."""
        super().__init__(NODE_NAME, **kwargs)
        p = declare_parameters(self, PARAMS, _check_pacing)
        self._lockstep = bool(p['lockstep'])
        self._real_time_factor = float(p['real_time_factor'])
        self._command_timeout_s = float(p['command_timeout_s'])
        self._joint_state_every = max(1, round(SIM_RATE_HZ / float(p['joint_state_rate_hz'])))
        self._stop_when_fallen = bool(p['stop_when_fallen'])
        self._random_push_period_s = float(p['random_push_period_s'])
        self._push_rng = np.random.default_rng(int(p['random_push_seed']))
        self._profile = profile = profile_for(str(p['robot']))
        self._joint_names = profile.joint_names
        self._push_distribution = PushDistribution.for_robot(profile) \
            if profile.name != DEFAULT_ROBOT else PushDistribution()
        self.add_post_set_parameters_callback(self._apply_parameters)

        gait, reflex, stabilizer = controller_configs(profile)
        self._q0, self._torso0 = BalanceController(gait, reflex, stabilizer=stabilizer,
                                                   profile=profile).initial_posture()
        try:
            self._sim = Simulator(profile=profile)
        except RuntimeError as error:
            raise NodeStartupError(str(error)) from error

        self._sensors = SimulatedSensors(self, float(p['sensor_noise_scale']), int(p['sensor_seed']),
                                         _driver_timing(p, profile), profile) \
            if p['publish_sensors'] else None
        #: The measurement (the exact state on ground_truth with sensors), published and handed
        #: to in-process consumers (the controller in ``simulated_robot``).
        self.output = Output(create_publisher(self, MeasurementMsg,
                                              MEASUREMENT if self._sensors is None else GROUND_TRUTH))
        self._clock_pub = create_publisher(self, Clock, CLOCK)
        self._joint_state_pub = create_publisher(self, JointState, JOINT_STATES)
        self._push_pub = create_publisher(self, WrenchStamped, PUSH)
        self._command_sub = None if in_process_controller else create_subscription(
            self, JointState, JOINT_COMMANDS, self._on_command)
        self._commands_connected = False   # an in-process controller (connect_controller)
        self._in_publish = False            # publishing a sample (an in-process command may come)
        # Resumes the in-process lock-step loop from the executor (see _advance).
        self._continue = self.create_guard_condition(self._on_continue) \
            if in_process_controller else None
        create_subscription(self, WrenchStamped, PUSH_REQUEST, self._on_push_request)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(SetBool, '~/pause', self._on_pause)

        #: Counters by event name (reported in /diagnostics).
        self.counts = {'worlds': 0, 'steps': 0, 'measurements': 0, 'joint_states': 0,
                       'pushes': 0, 'missed_commands': 0, 'late_commands': 0}
        self._bad_commands = InputErrors(self)
        self._bad_push_requests = InputErrors(self)
        self._command = self._q0.copy()
        self._m: Measurement            # the latest sample, set by _begin_run
        self._published = False             # current sample published?
        self._awaiting_ns: Optional[int] = None
        self._command_ready = False
        self._published_wall = 0.0
        self._hold: Optional[str] = None     # why the world is not stepping, None if running
        self._pending_push: Optional[PushSpec] = None
        self._push_busy_until_s = 0.0
        self._next_random_push_s = math.inf
        self._t_fallen: Optional[float] = None
        self._pace_anchor = (0.0, 0.0)       # (wall [s], simulation [s])
        self._report_anchor = (time.monotonic(), 0)     # (wall [s], steps)
        self._missed_at_report = 0

        self.create_timer(_WATCHDOG_PERIOD_S, self._on_watchdog, clock=steady_clock())
        self._step_timer = None
        if not self._lockstep:
            self._step_timer = self.create_timer(DT_S / self._real_time_factor,
                                                 self._on_step_timer, clock=steady_clock())
        self._diagnostics = Diagnostics(self, self._report, lambda: ros_qos.sim_ns(self._m.t),
                                        [s for s in (self._command_sub,) if s is not None])
        self._begin_run(None if p['autostart'] else 'waiting for ~/reset')
        self.get_logger().info(
            f'simulator ready: lockstep={self._lockstep}, real_time_factor='
            f'{self._real_time_factor}, random_push_period_s={self._random_push_period_s}')

    # -- parameters ------------------------------------------------------------------------
    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'real_time_factor':
                self._real_time_factor = float(parameter.value)
                self._pace_anchor = (time.monotonic(), self._m.t)
                if self._step_timer is not None:
                    self._step_timer.timer_period_ns = round(DT_S / self._real_time_factor * 1e9)
            elif parameter.name == 'command_timeout_s':
                self._command_timeout_s = float(parameter.value)
            elif parameter.name == 'stop_when_fallen':
                self._stop_when_fallen = bool(parameter.value)

    # -- runs ------------------------------------------------------------------------------
    def _begin_run(self, hold: Optional[str] = None) -> None:
        """A fresh world at t = 0, published as soon as the consumers are there (unless
        held for ``hold``)."""
        self._m = self._sim.reset(self._q0, self._torso0)
        self._command = self._q0.copy()
        self._published = False
        self._command_ready = False
        self._awaiting_ns = None
        self._hold = hold
        self._pending_push = None
        self._push_busy_until_s = 0.0
        self._next_random_push_s = self._random_push_period_s or math.inf
        self._t_fallen = None
        self.counts['worlds'] += 1
        if self._sensors is not None:
            self._sensors.new_world(self.counts['worlds'])
        if hold is None:
            self._try_start()

    def connect_controller(self, commands: Output) -> None:
        """Take the joint commands from ``commands`` (a controller node of this process)."""
        if self._command_sub is not None:
            raise ValueError('the simulator was built to subscribe to its commands')
        take_from(self, JOINT_COMMANDS, commands, self._on_command)
        self._commands_connected = True
        if self._hold is None and not self._published:
            self._try_start()

    def _try_start(self) -> None:
        """Publish the first sample of the run once someone listens (and, in lock-step,
        someone commands)."""
        if self._sensors is None:
            listened = self.output.consumers or self.output.publisher.get_subscription_count()
        else:
            listened = self._joint_state_pub.get_subscription_count()
        if not listened:
            return
        if self._lockstep and not (self._commands_connected or (
                self._command_sub is not None and self._command_sub.get_publisher_count())):
            return
        self._pace_anchor = (time.monotonic(), self._m.t)
        self._publish_sample(self._m)
        if self._command_ready and self._continue is not None:
            self._continue.trigger()        # answered in process: step from the executor

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self._begin_run()
        response.success = True
        response.message = f'fresh world at t = 0 s (world {self.counts["worlds"]} since start)'
        self.get_logger().info(response.message)
        return response

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        if request.data:
            self._hold = self._hold or _PAUSED
        elif self._hold == _PAUSED:
            self._hold = None
            self._pace_anchor = (time.monotonic(), self._m.t)
            self._published_wall = time.monotonic()
            if self._command_ready:
                self._advance()          # the command of the held sample came during the pause
        response.success = True
        response.message = f'holding: {self._hold}' if self._hold else 'running'
        return response

    # -- inputs ----------------------------------------------------------------------------
    def _on_command(self, msg: JointState) -> None:
        try:
            sample = messages.joint_state_reading(msg)
            if not np.isfinite(sample.position).all():
                raise WireFormatError('joint command positions are not finite')
            if sample.names != self._joint_names:
                raise WireFormatError(f'joint names {list(sample.names)} are not the robot\'s '
                                      f'{len(self._joint_names)} joints in URDF order')
        except WireFormatError as error:
            self._bad_commands.reject('joint command', error)
            return
        if not self._lockstep:
            self._command = sample.position
            return
        stamp_ns = messages.stamp_ns(msg)
        if stamp_ns != self._awaiting_ns or self._command_ready:
            self.counts['late_commands'] += 1
            return
        self._command = sample.position
        self._command_ready = True
        if not self._in_publish:            # in process, the loop in _advance() goes on
            self._advance()

    def _on_push_request(self, msg: WrenchStamped) -> None:
        try:
            push = ros_qos.push_request_from_msg(msg, self._m.t, DT_S)
            if self._push_busy():
                raise ValueError('another push is scheduled or still acting '
                                 f'(until {self._push_busy_until_s:.3f} s)')
        except ValueError as error:
            self._bad_push_requests.reject('push request', error)
            return
        self._schedule_push(push)

    def _push_busy(self) -> bool:
        """A push is scheduled or still acting (the simulator holds one push at a time)."""
        return self._pending_push is not None or self._m.t < self._push_busy_until_s - 1e-9

    def _schedule_push(self, push: PushSpec) -> None:
        self._sim.schedule_push(push)
        self._pending_push = push
        self._push_busy_until_s = push.t_force_end
        self.get_logger().info(
            f'push scheduled at {push.t_push:.3f} s: {push.force_n:.1f} N, '
            f'{push.angle_deg:.1f} deg from the heading, {push.height_m:+.3f} m above the CoM')

    # -- stepping --------------------------------------------------------------------------
    def _on_watchdog(self) -> None:
        if self._hold is not None:
            return
        if not self._published:
            self._try_start()
        elif (self._lockstep and not self._command_ready
              and time.monotonic() - self._published_wall > self._command_timeout_s):
            self.counts['missed_commands'] += 1
            self.get_logger().warning(
                f'no joint command for t = {self._m.t:.3f} s within {self._command_timeout_s} s: '
                f'stepping with the last command ({self.counts["missed_commands"]} missed)',
                throttle_duration_sec=1.0)
            self._advance()

    def _on_step_timer(self) -> None:
        if self._hold is None and self._published:
            self._advance()

    def _advance(self) -> None:
        """Step once with the current command and publish the new sample.

        With the controller in process its command arrives while the sample is published:
        then step on, up to :data:`_STEPS_PER_WAKEUP` steps, and continue from the executor
        (a guard condition) so that timers, services and the other inputs (the fall trigger,
        push requests) are served in between.
        """
        for _ in range(_STEPS_PER_WAKEUP):
            if self._hold is not None:
                return
            self._step_and_publish()
            if not (self._lockstep and self._command_ready):
                return                      # the command comes later, from another process
        if self._continue is not None:
            self._continue.trigger()

    def _on_continue(self) -> None:
        if self._command_ready and self._published:
            self._advance()

    def _step_and_publish(self) -> None:
        if self._lockstep:
            self._pace()
        self._sim.set_joint_targets(self._command)
        m = self._sim.step()
        self._m = m
        self.counts['steps'] += 1
        pending = self._pending_push
        if pending is not None and m.t > pending.t_push + DT_S / 2:
            self._push_pub.publish(ros_qos.push_to_msg(pending.t_push, m.push_force))
            self.counts['pushes'] += 1
            self._pending_push = None
        if m.t >= self._next_random_push_s - 1e-9:
            self._next_random_push_s += self._random_push_period_s
            if not self._push_busy():
                drawn = self._push_distribution.sample(self._push_rng)
                self._schedule_push(replace(drawn, t_push=round(m.t, 9)))
        self._publish_sample(m)

    def _pace(self) -> None:
        """Lock-step pacing: sleep until wall time allows the next step."""
        if self._real_time_factor <= 0.0:
            return
        wall0, sim0 = self._pace_anchor
        due = wall0 + (self._m.t + DT_S - sim0) / self._real_time_factor
        ahead = due - time.monotonic()
        if ahead > 0.0:
            time.sleep(ahead)
        elif ahead < -_MAX_PACING_LAG_S:
            self._pace_anchor = (time.monotonic(), self._m.t)

    def _publish_sample(self, m: Measurement) -> None:
        # Await sample k's command before publishing it: in process it arrives during publish.
        self._published = True
        stamp_ns = ros_qos.sim_ns(m.t)
        self._awaiting_ns = stamp_ns
        self._command_ready = False
        self._published_wall = time.monotonic()
        # /clock first: a node reading this sample's stamp against its ROS clock sees its time.
        self._clock_pub.publish(Clock(clock=ros_qos.stamp(stamp_ns)))
        self._in_publish = True
        try:
            self.output.hand_off(messages.StampedMeasurement(stamp_ns, ODOM_FRAME, '', m),
                                 partial(messages.measurement_msg, ros_qos.TYPES, stamp_ns,
                                         ODOM_FRAME, m))
        finally:
            self._in_publish = False
        self.counts['measurements'] += 1
        if self._sensors is not None:
            self.counts['joint_states'] += self._sensors.publish(self._sim, self._joint_state_pub)
        elif self._sim.tick % self._joint_state_every == 0:
            q, dq, effort = self._sim.joint_states()
            self._joint_state_pub.publish(
                ros_qos.joint_state_to_msg(stamp_ns, self._joint_names, q, dq, effort))
            self.counts['joint_states'] += 1
        if self._t_fallen is None and m.fallen:
            self._t_fallen = m.t
            self.get_logger().info(f'robot fallen at t = {m.t:.3f} s')
            if self._stop_when_fallen:
                self._hold = 'robot fallen (stop_when_fallen)'

    # -- diagnostics -----------------------------------------------------------------------
    def _report(self) -> Report:
        wall0, steps0 = self._report_anchor
        now = time.monotonic()
        achieved = (self.counts['steps'] - steps0) * DT_S / (now - wall0)
        self._report_anchor = (now, self.counts['steps'])
        missed = self.counts['missed_commands'] - self._missed_at_report
        self._missed_at_report = self.counts['missed_commands']
        rejected = (self._bad_commands.new_since_last_call()
                    + self._bad_push_requests.new_since_last_call())
        values = {'t_s': f'{self._m.t:.3f}', 'real_time_factor_achieved': f'{achieved:.3f}',
                  'real_time_factor': self._real_time_factor, 'lockstep': self._lockstep,
                  't_fallen_s': self._t_fallen, 'invalid_commands': self._bad_commands.count,
                  'push_requests_rejected': self._bad_push_requests.count,
                  'last_error': self._bad_commands.last or self._bad_push_requests.last,
                  **self.counts}
        if missed:
            return LEVEL_WARN, f'{missed} commands missed (controller late or absent)', values
        if rejected:
            return LEVEL_WARN, f'{rejected} invalid commands or push requests', values
        if self._hold is not None:
            return LEVEL_OK, f'holding: {self._hold}', values
        return LEVEL_OK, 'running', values

    def destroy_node(self) -> None:
        self._sim.close()
        super().destroy_node()


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.simulator_node --ros-args ...``."""
    return run_node(SimulatorNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
