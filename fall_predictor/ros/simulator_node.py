"""simulator_node: the simulated humanoid, lock-stepped with the controller.

The robot (``robot``, a profile) walked by its controller (``controller``: C_bal or a learned
policy the profile names; '' = the profile's default) in its simulator (``simulator``: PyBullet or
MuJoCo; '' = the profile's), at the physics step that controller needs (a learned policy's deploy
step, else the engine's own: PyBullet 1 ms; :mod:`fall_predictor.ros.simulated_world`), from the
controller's starting posture. Publishes, all stamped with simulation time:

* ``/fall_predictor/measurement`` and ``/clock`` every physics step;
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

Subscribes to ``/fall_predictor/joint_commands`` (the controller node's joint targets, every
joint of the robot in the profile's order) and to ``/fall_predictor/push_request`` (see
:data:`~fall_predictor.ros.health.PUSH_REQUEST`). The robot's drives track the targets with a
learned policy's PD gains (its deploy config's: they are the drives' configuration, not part of
the command) or with the robot's own servos under C_bal.

**A learned policy** walks on the robot's sensors, never on the simulator's state: it needs
``publish_sensors`` (the node refuses to start without), with joint states and IMU readings at
every physics step; each sample's sensor messages are published before its command is awaited.

**Lock-step** (``lockstep``, default true): after publishing sample k the node waits for the
joint command stamped with sample k's time (the stamp of its joint states: a policy answers each
joint state sample), applies it and steps, so the robot obeys the controller exactly and a run
is deterministic. If no matching command arrives within ``command_timeout_s`` of wall time, it
steps with the last command and counts a missed command (reported in ``/diagnostics``). Without
lock-step, a wall-clock timer steps the world at ``real_time_factor`` with the latest command
received. A run starts (sample t = 0 is published) only once the measurement (with sensors:
``/joint_states``, and for a policy ``/imu/data`` too) has a subscriber and, in lock-step, the
command topic a publisher; other late subscribers miss the first samples. For a complete record
from t = 0, set ``autostart`` false and call ``~/reset`` once every node's ``/diagnostics``
reports empty ``unmatched_inputs``, as the bring-up does.

**Pacing**: ``real_time_factor`` 1.0 keeps simulation time from running ahead of wall time;
0 steps as fast as the controller answers (lock-step only). A pipeline slower than real time
simply runs slower (the achieved factor is in ``/diagnostics``).

**Pushes** (method §3): a constant horizontal force for 0.1 s on the torso. A push request gives
the onset (header stamp, simulation time, rounded to the physics step; a past time means the next
step), the force in the
robot's heading frame and its torque about the CoM, ``(0, 0, h) x F``, from which the
application height ``h`` above the CoM is recovered. With ``random_push_period_s`` > 0 the node
also pushes by itself every period of simulation time, drawing force, direction and height
from :class:`~fall_predictor.sim.pushes.PushDistribution` seeded with ``random_push_seed``. A
request while a push is still acting is rejected (logged and counted).

**Fallen**: with ``stop_when_fallen`` the world stops stepping at the first fallen sample (CoM
below the profile's ``fallen_com_height_m``, method §4); otherwise it keeps going. ``~/reset`` (std_srvs/Trigger) starts a fresh world at
t = 0 (the other nodes notice time going backwards and reset themselves); ``~/pause``
(std_srvs/SetBool) holds the world (true) or lets it go on (false).
"""
from __future__ import annotations

import math
import time
from functools import partial
from dataclasses import replace
from typing import Optional

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import SetBool, Trigger

from fall_predictor.profiles.profile import DEFAULT_ROBOT
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.robots import profile_for
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.health import Diagnostics, InputErrors, Report, steady_clock
from fall_predictor.ros.parameters import NodeStartupError, declare_parameters
from fall_predictor.ros.runner import run_node
from fall_predictor.ros.in_process import Output, take_from
from fall_predictor.ros.simulated_world import (CommandDrives, check_policy_timing,
                                                controller_choice, make_node_world,
                                                walking_controller)
from fall_predictor.ros.simulator_params import PARAMS, check_pacing, driver_timing
from fall_predictor.sim.pushes import PushDistribution
from fall_predictor.monitor.records import Measurement, PushSpec
from fall_predictor.ros.simulated_sensors import SimulatedSensors
from fall_predictor.contract import messages
from fall_predictor.contract.topics import (CLOCK, GROUND_TRUTH, JOINT_COMMANDS, JOINT_STATES,
                                            MEASUREMENT, ODOM_FRAME, PUSH, PUSH_REQUEST,
                                            WireFormatError)
from fall_predictor.msg import Measurement as MeasurementMsg
from fall_predictor.contract.wire import LEVEL_OK, LEVEL_WARN

NODE_NAME = 'simulator_node'
#: Period of the wall-clock check for a run start and for lock-step command timeouts [s].
_WATCHDOG_PERIOD_S = 0.01
#: Lock-step pacing gives up catching up with wall time when this far behind [s].
_MAX_PACING_LAG_S = 0.1
_PAUSED = 'paused (~/pause)'
#: Lock-step with an in-process controller: steps per executor wake-up (see ``_advance``).
_STEPS_PER_WAKEUP = 5

class SimulatorNode(Node):
    """Owns one world of :mod:`fall_predictor.sim.world`; see the module documentation."""

    def __init__(self, in_process_controller: bool = False, **kwargs: object) -> None:
        """``in_process_controller``: the joint commands come from a controller node of the same
        process (:meth:`connect_controller`, ``simulated_robot``), not from a subscription;
        ``kwargs`` go to ``Node``."""
        super().__init__(NODE_NAME, **kwargs)
        p = declare_parameters(self, PARAMS, check_pacing)
        self._lockstep = bool(p['lockstep'])
        self._real_time_factor = float(p['real_time_factor'])
        self._command_timeout_s = float(p['command_timeout_s'])
        self._stop_when_fallen = bool(p['stop_when_fallen'])
        self._random_push_period_s = float(p['random_push_period_s'])
        self._push_rng = np.random.default_rng(int(p['random_push_seed']))
        self._profile = profile = profile_for(str(p['robot']))
        self._joint_names = profile.joint_names
        self.add_post_set_parameters_callback(self._apply_parameters)

        self._choice = choice = controller_choice(profile, str(p['controller']), str(p['simulator']))
        # Random pushes: the protocol's, with the force range of the controller's datasets.
        forces = tuple(profile.push_force_range_n(choice.name))
        self._push_distribution = PushDistribution(force_n=forces) \
            if profile.name != DEFAULT_ROBOT or choice.is_policy else PushDistribution()
        timing = driver_timing(p, profile)
        if choice.is_policy and not p['publish_sensors']:
            raise NodeStartupError(f'controller {choice.name!r} is a learned policy: it walks on the '
                                   'robot\'s sensor topics, which need publish_sensors true')
        self._drives = CommandDrives(profile, walking_controller(profile, choice))
        self._posture = self._drives.posture
        self._world = make_node_world(profile, choice)
        #: The physics step [s]: every sample, pacing and push onset is on its grid.
        self.dt_s = float(self._world.dt_s)
        if choice.is_policy:
            check_policy_timing(timing, self.dt_s, choice)
        self._joint_state_every = max(1, round(1.0 / (self.dt_s * float(p['joint_state_rate_hz']))))
        self._q0 = np.array([self._posture.joint_angles.get(n, 0.0) for n in self._joint_names])

        self._sensors = SimulatedSensors(self, float(p['sensor_noise_scale']), int(p['sensor_seed']),
                                         timing, profile, self.dt_s) \
            if p['publish_sensors'] else None
        #: Period [s] of the measurement stream a run drives (the estimator's, driven by the
        #: joint states, with sensors).
        self.sample_period_s = self.dt_s if self._sensors is None else max(
            self.dt_s, 1.0 / timing.joint_rate_hz)
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
        self._command = self._drives(self._q0)
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
            self._step_timer = self.create_timer(self.dt_s / self._real_time_factor,
                                                 self._on_step_timer, clock=steady_clock())
        self._diagnostics = Diagnostics(self, self._report, lambda: ros_qos.sim_ns(self._m.t),
                                        [s for s in (self._command_sub,) if s is not None])
        try:
            self._begin_run(None if p['autostart'] else 'waiting for ~/reset')
        except ValueError as error:     # the engine cannot start the robot in that posture
            raise NodeStartupError(f'{choice.simulator} cannot start {profile.name} under '
                                   f'{choice.name}: {error}') from error
        self.get_logger().info(
            f'simulator ready: {profile.name} under {choice.name} in {choice.simulator} '
            f'({self.dt_s * 1e3:g} ms steps), lockstep={self._lockstep}, real_time_factor='
            f'{self._real_time_factor}, random_push_period_s={self._random_push_period_s}')

    # -- parameters ------------------------------------------------------------------------
    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'real_time_factor':
                self._real_time_factor = float(parameter.value)
                self._pace_anchor = (time.monotonic(), self._m.t)
                if self._step_timer is not None:
                    self._step_timer.timer_period_ns = round(self.dt_s / self._real_time_factor * 1e9)
            elif parameter.name == 'command_timeout_s':
                self._command_timeout_s = float(parameter.value)
            elif parameter.name == 'stop_when_fallen':
                self._stop_when_fallen = bool(parameter.value)

    # -- runs ------------------------------------------------------------------------------
    def _begin_run(self, hold: Optional[str] = None) -> None:
        """A fresh world at t = 0, published as soon as the consumers are there (unless
        held for ``hold``)."""
        self._m = self._world.start(self._posture)
        self._command = self._drives(self._q0)
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
            listened = self._joint_state_pub.get_subscription_count() and (
                not self._choice.is_policy or self._sensors.imu_subscribed)
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
            self._command = self._drives(sample.position)
            return
        stamp_ns = messages.stamp_ns(msg)
        if stamp_ns != self._awaiting_ns or self._command_ready:
            self.counts['late_commands'] += 1
            return
        self._command = self._drives(sample.position)
        self._command_ready = True
        if not self._in_publish:            # in process, the loop in _advance() goes on
            self._advance()

    def _on_push_request(self, msg: WrenchStamped) -> None:
        try:
            push = ros_qos.push_request_from_msg(msg, self._m.t, self.dt_s)
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
        self._world.schedule_push(push)
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
        self._world.apply(self._command)
        m = self._world.step()
        self._m = m
        self.counts['steps'] += 1
        pending = self._pending_push
        if pending is not None and m.t > pending.t_push + self.dt_s / 2:
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
        due = wall0 + (self._m.t + self.dt_s - sim0) / self._real_time_factor
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
        # The sample's sensors before its measurement is handed off: a controller of this process
        # may answer (and the world step on) during the hand-off.
        if self._sensors is not None:
            self.counts['joint_states'] += self._sensors.publish(self._world, self._joint_state_pub)
        elif self._world.tick % self._joint_state_every == 0:
            q, dq, effort = self._world.joint_states()
            self._joint_state_pub.publish(
                ros_qos.joint_state_to_msg(stamp_ns, self._joint_names, q, dq, effort))
            self.counts['joint_states'] += 1
        self._in_publish = True
        try:
            self.output.hand_off(messages.StampedMeasurement(stamp_ns, ODOM_FRAME, '', m),
                                 partial(messages.measurement_msg, ros_qos.TYPES, stamp_ns,
                                         ODOM_FRAME, m))
        finally:
            self._in_publish = False
        self.counts['measurements'] += 1
        if self._t_fallen is None and m.com[2] < self._profile.fallen_com_height_m:
            self._t_fallen = m.t
            self.get_logger().info(f'robot fallen at t = {m.t:.3f} s')
            if self._stop_when_fallen:
                self._hold = 'robot fallen (stop_when_fallen)'

    # -- diagnostics -----------------------------------------------------------------------
    def _report(self) -> Report:
        wall0, steps0 = self._report_anchor
        now = time.monotonic()
        achieved = (self.counts['steps'] - steps0) * self.dt_s / (now - wall0)
        self._report_anchor = (now, self.counts['steps'])
        missed = self.counts['missed_commands'] - self._missed_at_report
        self._missed_at_report = self.counts['missed_commands']
        rejected = (self._bad_commands.new_since_last_call()
                    + self._bad_push_requests.new_since_last_call())
        values = {'t_s': f'{self._m.t:.3f}', 'real_time_factor_achieved': f'{achieved:.3f}',
                  'controller': self._choice.name, 'simulator': self._choice.simulator,
                  'dt_s': self.dt_s, 'sample_period_s': self.sample_period_s,
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
        self._world.close()
        super().destroy_node()


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.simulator_node --ros-args ...``."""
    return run_node(SimulatorNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
