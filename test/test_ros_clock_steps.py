"""``fall_monitor --estimator`` under ``use_sim_time`` when the simulator resets: ``/clock`` and
every sensor stamp go back to zero. The monitor starts a new timeline in every node at once (the
estimator confirms the step, the feature and predictor nodes take it in process), its states are
OK again after the time rule's confirmation whether the new ``/clock`` arrives before or after the
first new samples, a fall latched before stays latched, and nothing says FALLING."""
from __future__ import annotations

import numpy as np
import pytest
import rclpy.node
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, String
from test_nodes_support import ros_context, test_domain_id, write_momentum_model

from fall_predictor.contract import cdr
from fall_predictor.contract.topics import FALLING, STATE
from fall_predictor.monitor.fall_monitor import STATUS_OK
from fall_predictor.monitor.timeline import TimelineConfig
from fall_predictor.msg import FallState
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.endpoints import create_subscription
from fall_predictor.ros.fall_monitor import MONITOR_NODES, in_process_chain
from fall_predictor.ros.runner import spin_until
from fall_predictor.ros.state_estimator_node import StateEstimatorNode
from fall_predictor.sim.drivers import DriverTiming, driver_messages
from fall_predictor.sim.sensors import SensorParams, apply_sensors
from fall_predictor.sim.trajectory import run_trajectory

DOMAIN = test_domain_id(79)
MS = 1_000_000


@pytest.fixture(scope='module')
def walk():
    """0.8 s of the unpushed walk as the simulator's drivers publish it (simulation time)."""
    run = run_trajectory(None, 0.8, record_sensors=True)
    samples = apply_sensors(run.sensor_truths, SensorParams(), seed=5)
    return list(driver_messages(samples, DriverTiming()))


@pytest.mark.parametrize('clock_first', [True, False],
                         ids=['/clock reset first', 'samples before the new /clock'])
def test_a_simulator_reset_under_sim_time_starts_a_new_timeline_keeping_the_latch(
        tmp_path, walk, clock_first: bool) -> None:
    model = write_momentum_model(tmp_path / 'model.json')
    with ros_context(DOMAIN) as context:
        nodes = [make() for make in in_process_chain(
            (StateEstimatorNode, *MONITOR_NODES), context=context,
            parameter_overrides=[Parameter('model_path', value=str(model)),
                                 Parameter('use_sim_time', value=True),
                                 # The watchdogs run on wall time, and this test feeds the samples
                                 # at its own pace (a tick waits until /clock has arrived): on a
                                 # busy machine 0.5 s passed between two of them and a STALE state
                                 # came in the middle of the walk. Staleness is tested elsewhere.
                                 Parameter('stale_timeout_s', value=30.0)])]
        estimator, feature, predictor = nodes
        probe = rclpy.node.Node('clock_step_probe', context=context)
        clock = probe.create_publisher(Clock, '/clock', 10)
        states: list[tuple[int, int, str, bool]] = []
        create_subscription(probe, FallState, STATE, lambda m: states.append(
            (m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec, m.status, m.reason, m.latched)),
            lossless=True)
        trigger: list[bool] = []
        create_subscription(probe, Bool, FALLING, lambda m: trigger.append(m.data))
        executor = SingleThreadedExecutor(context=context)
        for node in (*nodes, probe):
            executor.add_node(node)

        def tick(ns: int) -> None:
            clock.publish(Clock(clock=ros_qos.stamp(ns)))
            spin_until(executor, lambda: predictor.get_clock().now().nanoseconds == ns, 2.0)

        def feed(readings) -> None:
            for k, (stream, r) in enumerate(readings):
                if stream == 'joints':
                    estimator._on_joint_state(cdr.joint_state_cdr(r))
                elif stream == 'imu':
                    estimator._on_imu(cdr.imu_cdr(r))
                else:
                    estimator._on_wrench(stream, cdr.wrench_cdr(r))
                if k % 200 == 199:
                    executor.spin_once(timeout_sec=0.0)
        try:
            estimator._on_description(String(data=rm.PROFILE.urdf_xml()))
            assert spin_until(executor, lambda: clock.get_subscription_count() >= 1
                              and predictor._state_pub.get_subscription_count() >= 1, 10.0)
            half = [(s, r) for s, r in walk if r.stamp_ns < 400 * MS]
            for start in range(0, 400, 20):        # /clock every 20 ms, the samples in between
                tick(start * MS)
                feed([(s, r) for s, r in half if start * MS <= r.stamp_ns < (start + 20) * MS])
            last_ns = max(r.stamp_ns for s, r in half if s == 'joints')
            assert spin_until(executor, lambda: any(st[0] == last_ns for st in states), 10.0)
            spin_until(executor, lambda: False, 0.2)
            assert all(status == STATUS_OK for _, status, _, _ in states[30:]), states[30]
            predictor._monitor._latched = True     # a fall triggered before the reset
            # The states of the first half (and any STALE state of the watchdog before the first
            # sample, stamped 0) end with the last sample's.
            # The simulator resets: /clock and the stamps start again from zero.
            again = [(s, r) for s, r in walk if r.stamp_ns < 300 * MS]
            if clock_first:
                tick(0)
                for start in range(0, 300, 20):
                    tick(start * MS)
                    feed([(s, r) for s, r in again if start * MS <= r.stamp_ns < (start + 20) * MS])
            else:
                feed([(s, r) for s, r in again if r.stamp_ns < 40 * MS])
                for start in range(40, 300, 20):
                    tick(start * MS)
                    feed([(s, r) for s, r in again if start * MS <= r.stamp_ns < (start + 20) * MS])
            boundary = max(i for i, st in enumerate(states) if st[0] == last_ns) + 1
            assert spin_until(executor, lambda: len(states) >= boundary + 290, 10.0)
            spin_until(executor, lambda: False, 0.2)
        finally:
            executor.shutdown()
            for node in (*nodes, probe):
                node.destroy_node()
    after = states[boundary:]
    # The first state of the new timeline is the time rule's fifth sample (4 ms), and every state
    # from there is OK (none STALE while /clock catches up, none DEGRADED), latched, never falling.
    jump = TimelineConfig().jump_samples
    assert after[0][0] == (jump - 1) * MS
    assert [stamp for stamp, *_ in after] == [k * MS for k in range(jump - 1, jump - 1 + len(after))]
    assert all(status == STATUS_OK for _, status, _, _ in after), next(
        s for s in after if s[1] != STATUS_OK)
    assert all(latched for *_, latched in after)
    assert False not in trigger[trigger.index(True):] if True in trigger else True
    # One new run in each node, the latter two taken in process from the estimator's.
    assert [n._timeline.jumps for n in (feature, predictor)] == [1, 1]
    assert estimator._pipeline.timeline.jumps == 1
    assert np.isfinite(after[-1][0])
