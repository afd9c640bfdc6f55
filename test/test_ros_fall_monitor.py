"""ros/fall_monitor.py: the nodes of one ``fall_monitor`` process hand their samples over in
process, and the states they publish are the library's offline ones."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import rclpy.node
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from test_nodes_support import MODEL_TAU_HIS_S, ros_context, test_domain_id, write_momentum_model

from fall_predictor.contract import messages
from fall_predictor.contract.topics import FEATURES, STATE
from fall_predictor.monitor.chain import base_tilt_rad
from fall_predictor.monitor.fall_monitor import STATUS_DEGRADED, STATUS_FALLEN, FallMonitor
from fall_predictor.monitor.features import FeatureSettings, extract_features
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.records import PushSpec
from fall_predictor.msg import FallState, Features
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.endpoints import create_subscription
from fall_predictor.ros.fall_monitor import MONITOR_NODES, in_process_chain
from fall_predictor.ros.robots import fallen_config_for
from fall_predictor.ros.runner import spin_until
from fall_predictor.sim.trajectory import run_trajectory

DOMAIN = test_domain_id(73)


def _offline_states(model: Path, measurements: list) -> list:
    """The library's extractor and predictor run offline over ``measurements`` with ``model``:
    the states the monitor nodes must publish."""
    lists, _ = load_model(model)
    extractor = FeatureSettings().extractor()
    offline = FallMonitor(lists, MODEL_TAU_HIS_S, fallen_config_for('asimo_like'),
                          FeatureSettings().sample_period_s, FeatureSettings().guard_com_height_m)
    return [offline.step(m.t, *extractor.update(m), base_tilt_rad(m.torso_rotation))[0]
            for m in measurements]


def _monitor_nodes(context, model: Path) -> list:
    """``fall_monitor``'s feature and predictor nodes, in process, with ``model`` (stamps near
    1970: no sample age check)."""
    return [make() for make in in_process_chain(
        MONITOR_NODES, context=context,
        parameter_overrides=[Parameter('model_path', value=str(model)),
                             Parameter('max_sample_age_s', value=0.0)])]


def test_fall_monitor_hands_each_features_message_to_the_predictor_in_process(tmp_path: Path
                                                                             ) -> None:
    """In ``fall_monitor`` the predictor has no features subscription: the feature node hands
    it every message directly, once and in order (its states equal the library's extractor and
    predictor run offline on the same measurements), and still publishes every features
    message for other processes (a probe receives them over DDS), with the base's attitude
    (method §8c) the library computes offline."""
    model = write_momentum_model(tmp_path / 'model.json')
    measurements = run_trajectory(PushSpec(450.0, 0.0, 0.1, 0.3), 1.2,
                                  stop_when_fallen=False).measurements
    outputs = _offline_states(model, measurements)
    expected = [o.falling for o in outputs]
    # The robot is down (FALLEN, no prediction) from its first sample with the CoM below 0.33 m
    # or the torso tilted beyond 60 degrees (it stays down: it does not get up).
    first_fallen = next(k for k, m in enumerate(measurements)
                        if m.com[2] < 0.33 or m.torso_rotation[2, 2] < math.cos(math.radians(60)))
    assert [o.status == STATUS_FALLEN for o in outputs] == [
        k >= first_fallen for k in range(len(outputs))]
    assert 0 < sum(expected) < len(expected)          # the push is predicted, not at once

    with ros_context(DOMAIN) as context:
        feature, predictor = _monitor_nodes(context, model)
        probe = rclpy.node.Node('in_process_probe', context=context)
        states: list[float] = []
        features: list[float] = []
        create_subscription(probe, FallState, STATE, lambda msg: states.append(msg.falling),
                            lossless=True)
        statuses: list[int] = []
        create_subscription(probe, FallState, STATE, lambda msg: statuses.append(msg.status),
                            lossless=True)
        attitudes: list = []

        def on_features(msg) -> None:
            features.append(messages.stamp_ns(msg))
            attitudes.append(np.array(msg.base_attitude))
        create_subscription(probe, Features, FEATURES, on_features, lossless=True)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(probe)
        try:
            assert not [s.topic_name for s in predictor.subscriptions
                        if s.topic_name.endswith('features')]
            assert spin_until(executor, lambda: feature.output.publisher.get_subscription_count()
                              >= 1 and predictor._state_pub.get_subscription_count() >= 1, 10.0)
            for k, m in enumerate(measurements):
                feature._on_measurement(messages.measurement_msg(
                    ros_qos.TYPES, ros_qos.sim_ns(m.t), 'odom', m))
                if k % 50 == 49:                # keep the reliable queues short
                    spin_until(executor, lambda: len(states) == k + 1, 10.0)
            assert spin_until(executor, lambda: len(states) == len(measurements)
                              and len(features) == len(measurements), 10.0)
        finally:
            executor.shutdown()
            for node in (probe, predictor, feature):
                node.destroy_node()
    assert [bool(v) for v in states] == expected
    assert statuses == [o.status for o in outputs]
    assert features == [ros_qos.sim_ns(m.t) for m in measurements]
    assert predictor.counts['features'] == len(measurements)
    offline, _ = extract_features(measurements, attitude=True)
    np.testing.assert_allclose(np.array(attitudes), offline[:, 15:], rtol=1e-9, atol=1e-9)
    assert np.ptp(offline[:, 15]) > 0.1 or np.ptp(offline[:, 16]) > 0.1    # the base tips over


def test_fall_monitor_without_other_subscribers_hands_decoded_samples_and_builds_no_message(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """With nobody of another process on ``fall_predictor/features``, the feature node hands the
    predictor the decoded features and builds no features message (building and decoding one
    cost more than the estimator); the states are still the library's offline ones, and a
    fault handed over in process (the state estimator's words for an implausible estimate) gets
    a DEGRADED state that says it."""
    model = write_momentum_model(tmp_path / 'model.json')
    measurements = run_trajectory(PushSpec(450.0, 0.0, 0.1, 0.3), 1.0,
                                  stop_when_fallen=False).measurements
    expected = [o.status for o in _offline_states(model, measurements)]
    built: list[int] = []
    features_msg = messages.features_msg
    monkeypatch.setattr(messages, 'features_msg',
                        lambda *args: built.append(1) or features_msg(*args))
    fault = 'implausible estimate: CoM height -1.0 m is outside [0.0, 2.0] m'
    # A domain of its own: the previous test's features probe may still be matched in DOMAIN
    # until DDS discovery notices it is gone.
    with ros_context(test_domain_id(74)) as context:
        feature, predictor = _monitor_nodes(context, model)
        probe = rclpy.node.Node('hand_off_probe', context=context)
        statuses: list[int] = []
        reasons: list[str] = []
        create_subscription(probe, FallState, STATE, lambda msg: statuses.append(msg.status)
                            or reasons.append(msg.reason), lossless=True)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(probe)
        try:
            assert spin_until(executor, lambda: predictor._state_pub.get_subscription_count() >= 1,
                              10.0)
            assert feature.output.publisher.get_subscription_count() == 0
            for k, m in enumerate(measurements):
                feature._take_measurement(messages.StampedMeasurement(
                    ros_qos.sim_ns(m.t), 'odom', '', m))
                if k % 50 == 49:                # keep the reliable queue short
                    spin_until(executor, lambda: len(statuses) == k + 1, 10.0)
            feature._take_measurement(messages.StampedMeasurement(
                ros_qos.sim_ns(measurements[-1].t) + 1_000_000, 'odom', fault, None))
            assert spin_until(executor, lambda: len(statuses) == len(measurements) + 1, 10.0)
        finally:
            executor.shutdown()
            for node in (probe, predictor, feature):
                node.destroy_node()
    assert statuses == expected + [STATUS_DEGRADED]
    assert reasons[-1] == fault
    assert built == []
    assert feature.counts['measurements'] == len(measurements) + 1
    assert feature._bad_inputs.count == 0 and feature.counts['faults'] == 1
    assert predictor.counts['features'] == len(measurements) + 1
    assert predictor.counts['degraded_states'] == 1
