"""Node building blocks without a running system: push requests, run detection, parameters,
and the predictor node's start-up (model loading, parameter validation) in and out of process."""
from __future__ import annotations

import dataclasses

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from test_nodes_support import (MODEL_TAU_HIS_S, MOMENTUM_THRESHOLD, ros_context, test_domain_id,
                                write_boosted_model, write_momentum_model)

from fall_predictor.ros.bringup import ros_environment
from fall_predictor.contract import messages
from fall_predictor.msg import FallState
from fall_predictor.monitor.fall_monitor import STATUS_DEGRADED
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.parameters import NodeStartupError, ParamSpec
from fall_predictor.ros.runner import spin_until
from fall_predictor.ros.simulated_robot import robot_nodes
from fall_predictor.sim.trajectory import run_trajectory
from fall_predictor.ros.feature_node import FeatureNode
from fall_predictor.ros.predictor_node import PredictorNode
from fall_predictor.monitor.features import FeatureSettings
from fall_predictor.monitor.model_file import load_model, save_model
from fall_predictor.ros.share import default_model_path
from fall_predictor.ros.conversions import (MAX_PUSH_HEIGHT_M, push_request_from_msg,
                                            push_request_to_msg)
from fall_predictor.monitor.records import PushSpec

DOMAIN = test_domain_id(70)


# -- push requests ---------------------------------------------------------------------------

@pytest.mark.parametrize('push', [PushSpec(450.0, 90.0, 0.1, 2.5),
                                  PushSpec(120.0, -135.0, -0.05, 3.0),
                                  PushSpec(300.0, 0.0, 0.25, 2.123)])
def test_push_request_round_trip(push: PushSpec) -> None:
    back = push_request_from_msg(push_request_to_msg(push), now_s=1.0, dt_s=0.001)
    assert back.force_n == pytest.approx(push.force_n)
    assert back.angle_deg == pytest.approx(push.angle_deg)
    assert back.height_m == pytest.approx(push.height_m)
    assert back.t_push == push.t_push and back.duration_s == 0.1


def test_push_request_onset_on_the_step_grid_and_never_in_the_past() -> None:
    msg = push_request_to_msg(PushSpec(100.0, 0.0, 0.0, 2.5004))
    assert push_request_from_msg(msg, now_s=1.0, dt_s=0.001).t_push == 2.5
    assert push_request_from_msg(msg, now_s=3.217, dt_s=0.001).t_push == 3.217


def _request(fx: float = 100.0, fy: float = 0.0, fz: float = 0.0, torque=(0.0, 0.0, 0.0),
             frame: str = 'base_footprint') -> WrenchStamped:
    msg = WrenchStamped()
    msg.header.frame_id = frame
    msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z = fx, fy, fz
    msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z = torque
    return msg


@pytest.mark.parametrize('msg,problem', [
    (_request(fz=50.0), 'horizontal'),
    (_request(frame='world'), 'frame_id'),
    (_request(torque=(0.0, 0.0, 3.0)), 'not (0, 0, h) x force'),
    (_request(torque=(5.0, 0.0, 0.0)), 'not (0, 0, h) x force'),
    (_request(torque=(0.0, 100.0 * (MAX_PUSH_HEIGHT_M + 0.5), 0.0)), 'exceeds'),
    (_request(fx=math.nan), 'finite'),
    (_request(fx=1e300), 'beyond 100000 N'),
])
def test_bad_push_requests_are_rejected_with_the_reason(msg: WrenchStamped, problem: str) -> None:
    with pytest.raises(ValueError, match=problem.replace('(', r'\(').replace(')', r'\)')):
        push_request_from_msg(msg, now_s=0.0, dt_s=0.001)


def test_empty_frame_means_heading_frame() -> None:
    assert push_request_from_msg(_request(frame=''), 0.0, 0.001).force_n == 100.0


# -- runs and parameters -----------------------------------------------------------------------

def test_a_run_report_keeps_why_its_states_were_unusable() -> None:
    """The bring-up's per-run report: unusable states after the run's first sample are counted
    by kind of reason (the same fault with other measured values is one kind), the first few
    kinds by name with an example each, the rest together."""
    from fall_predictor.monitor.fall_monitor import STATUS_OK, STATUS_STALE, MonitorState
    from fall_predictor.ros.run_observation import MAX_REASONS, OTHER_REASONS, ObservedState, RunObservation
    run = RunObservation(PushSpec(100.0, 0.0, 0.1, 2.5))
    run.add_state(ObservedState(0.0, MonitorState(STATUS_STALE, 'no input yet')))   # not started
    run.add_measurement(run_trajectory(None, 0.001).measurements[0])
    late = 'sample arrived {:.3f} s after its stamp (max_sample_age_s 0.05)'
    states = [(STATUS_STALE, late.format(0.08)), (STATUS_OK, ''),
              (STATUS_DEGRADED, 'IMU reading is not finite'), (STATUS_STALE, late.format(0.123)),
              (STATUS_STALE, late.format(1.5))]
    states += [(STATUS_DEGRADED, f'joint j{k} stuck') for k in range(MAX_REASONS)]
    for k, (status, reason) in enumerate(states):
        run.add_state(ObservedState(0.001 * (k + 1), MonitorState(status, reason)))
    report = run.result(0, 4.0, 'balance')
    assert report['degraded_states'] == len(states) - 1
    late_kind = 'sample arrived # s after its stamp (max_sample_age_s #)'
    assert report['degraded_reasons'] == {
        late_kind: 3, 'IMU reading is not finite': 1,
        **{f'joint j{k} stuck': 1 for k in range(MAX_REASONS - 2)}, OTHER_REASONS: 2}
    assert report['degraded_reason_examples'] == {
        late_kind: late.format(0.08), 'IMU reading is not finite': 'IMU reading is not finite',
        **{f'joint j{k} stuck': f'joint j{k} stuck' for k in range(MAX_REASONS - 2)}}


def test_a_new_run_begins_where_its_stream_goes_back_in_time_even_without_its_first_messages(
) -> None:
    """After a reset the previous run's messages still in flight are dropped; each stream (one
    writer, in order) begins the new run at its first message stamped before the latest one
    received, or before NEW_RUN_T_S: an observer that lost the new run's first half second
    (its queue overflowed) or a monitor that did (best-effort inputs) still follows the run."""
    from fall_predictor.ros.run_observation import NEW_RUN_T_S, RunBoundary
    boundary = RunBoundary()
    assert boundary.take_sample(3.2) and boundary.take_state(3.2)   # a first run: all taken
    boundary.reset()
    # The old run's last messages, in flight, only go forward: dropped.
    assert not boundary.take_sample(3.201) and not boundary.take_sample(3.202)
    assert not boundary.take_state(3.201)
    # The new run's first 0.7 s of states were lost: its first state, 0.7 s, goes back in time.
    assert boundary.take_sample(0.001) and boundary.take_sample(0.002)
    assert boundary.take_state(NEW_RUN_T_S + 0.2) and boundary.take_state(3.4)
    assert boundary.take_sample(3.4)                    # and the rest of the run
    boundary.reset()
    assert boundary.take_state(0.001)                   # the usual case: stamped near 0
    assert not boundary.take_sample(3.41)               # this stream's old run, in flight
    boundary = RunBoundary()
    assert boundary.take_sample(0.3)                    # the first run, with no latest stamp
    boundary.reset()
    assert not boundary.take_state(NEW_RUN_T_S)         # a state forward of all received ones


def test_a_run_report_counts_the_samples_its_observer_missed() -> None:
    """Gaps in the 1 kHz stamps the observer received are its own losses; its ``t_fallen`` is
    the first fallen sample it received (late by at most what it lost)."""
    from fall_predictor.ros.run_observation import RunObservation
    run = RunObservation(PushSpec(100.0, 0.0, 0.1, 2.5))
    first = run_trajectory(None, 0.001).measurements[0]
    received = [1, 2, 3, 7, 8, 108, 109]               # ms: 3 lost, then 99 (the fall at 0.010)
    for ms in received:
        run.add_measurement(dataclasses.replace(first, t=ms / 1000.0, non_foot_contact=ms >= 10))
    report = run.result(0, 4.0, 'balance')
    assert report['observer_lost_samples'] == 3 + 99
    assert report['t_fallen'] == 0.108 and report['t_end'] == 0.109


def test_param_spec_checks_type_finiteness_and_range() -> None:
    spec = ParamSpec('tau_his_s', 0.05, 'window [s]', 0.0, 2.0)
    assert spec.check(0.5) is None
    assert 'must be a float' in spec.check(1)
    assert 'finite' in spec.check(math.nan)
    assert 'outside its range [0.0, 2.0]' in spec.check(2.5)
    descriptor = spec.descriptor()
    assert descriptor.floating_point_range[0].to_value == 2.0
    assert ParamSpec('seed', 0, 'seed', 0, 10).descriptor().integer_range[0].to_value == 10
    assert ParamSpec('on', True, 'flag').check(True) is None


# -- predictor start-up ------------------------------------------------------------------------

def test_predictor_node_defaults_tau_his_to_the_models_recommendation(tmp_path: Path) -> None:
    model = write_momentum_model(tmp_path / 'model.json')
    with ros_context(DOMAIN) as context:
        node = PredictorNode(context=context,
                             parameter_overrides=[Parameter('model_path', value=str(model))])
        try:
            assert node.get_parameter('tau_his_s').value == MODEL_TAU_HIS_S
        finally:
            node.destroy_node()


def test_boosted_models_decision_threshold_is_a_run_time_parameter_lists_have_none(tmp_path: Path) -> None:
    boosted = write_boosted_model(tmp_path / 'boosted.json')
    lists = write_momentum_model(tmp_path / 'lists.json')
    x = np.zeros(15)
    x[2], x[3] = 0.59, MOMENTUM_THRESHOLD + 5.0               # the stump's score: 1.5
    with ros_context(DOMAIN) as context:
        node = PredictorNode(context=context, parameter_overrides=[
            Parameter('model_path', value=str(boosted)), Parameter('max_sample_age_s', value=0.0)])
        try:
            assert node.get_parameter('decision_threshold').value == 1.0   # the model's
            assert node.set_parameters([Parameter('decision_threshold', value=2.0)])[0].successful
            assert node._monitor.decision_threshold == 2.0
            for k in range(30):
                node._on_features(messages.features_msg(ros_qos.TYPES, 10**9 + k * 10**6, x, 0))
            assert not node._monitor.latched                 # 1.5 is not above 2.0
            assert node.set_parameters([Parameter('decision_threshold', value=1.4)])[0].successful
            for k in range(30, 60):
                node._on_features(messages.features_msg(ros_qos.TYPES, 10**9 + k * 10**6, x, 0))
            assert node._monitor.latched
        finally:
            node.destroy_node()
        node = PredictorNode(context=context, parameter_overrides=[Parameter('model_path', value=str(lists))])
        try:
            result = node.set_parameters([Parameter('decision_threshold', value=1.0)])[0]
            assert not result.successful and 'decision lists' in result.reason
        finally:
            node.destroy_node()
        with pytest.raises(NodeStartupError, match='decision_threshold is set, but the model holds '
                                                   'decision lists'):
            PredictorNode(context=context, parameter_overrides=[
                Parameter('model_path', value=str(lists)), Parameter('decision_threshold', value=1.0)])


def test_predictor_node_reports_the_models_learned_fall_direction(tmp_path: Path) -> None:
    """A model with a learned direction (here a constant turn of 0.5 rad to the left): the
    states and the FALLING event carry the momentum's direction turned by it."""
    from fall_predictor.monitor.fall_direction import DIRECTION_INPUT_NAMES, LearnedDirection
    from fall_predictor.monitor.model_file import load_model, save_model
    from fall_predictor.monitor.time_to_fall import RegressionTree
    path = write_momentum_model(tmp_path / 'model.json')
    lists, metadata = load_model(path)
    turn = RegressionTree((-1,), (0.0,), (-1,), (-1,), (0.5,), n_inputs=len(DIRECTION_INPUT_NAMES))
    save_model(path, lists, dataclasses.replace(metadata, fall_direction=LearnedDirection((turn,))))
    x = np.zeros(15)
    x[2], x[3] = 0.59, MOMENTUM_THRESHOLD + 5.0              # falling forward
    with ros_context(DOMAIN) as context:
        node = PredictorNode(context=context, parameter_overrides=[
            Parameter('model_path', value=str(path)), Parameter('max_sample_age_s', value=0.0)])
        states, events = [], []
        node._state_pub.publish = states.append
        node._event_pub.publish = events.append
        try:
            for k in range(30):
                node._on_features(messages.features_msg(ros_qos.TYPES, 10**9 + k * 10**6, x, 0))
        finally:
            node.destroy_node()
    # The node publishes its states serialized (contract/cdr.fall_state_cdr).
    falling = [messages.fall_state_from_msg(deserialize_message(m, FallState))[1] for m in states]
    falling = [state for state in falling if state.falling]
    assert falling and all(state.fall_direction == pytest.approx((math.cos(0.5), math.sin(0.5)))
                           for state in falling)
    assert len(events) == 1
    assert (events[0].direction.x, events[0].direction.y) == pytest.approx(
        (math.cos(0.5), math.sin(0.5)))


def test_predictor_node_refuses_a_missing_model_in_process(tmp_path: Path) -> None:
    missing = tmp_path / 'nowhere.json'
    with ros_context(DOMAIN) as context:
        with pytest.raises(NodeStartupError, match='nowhere.json'):
            PredictorNode(context=context,
                          parameter_overrides=[Parameter('model_path', value=str(missing))])


def _model_with_settings(path: Path, settings: FeatureSettings) -> Path:
    lists, metadata = load_model(write_momentum_model(path))
    save_model(path, lists, dataclasses.replace(metadata, feature_settings=settings))
    return path


def test_feature_and_predictor_nodes_adopt_the_models_feature_settings(tmp_path: Path) -> None:
    settings = FeatureSettings(rate_window_s=0.02, edge_tolerance_m=0.005, sample_period_s=0.002,
                               guard_com_height_m=0.4)
    model = _model_with_settings(tmp_path / 'model.json', settings)
    with ros_context(DOMAIN) as context:
        features = FeatureNode(context=context,
                               parameter_overrides=[Parameter('model_path', value=str(model))])
        predictor = PredictorNode(context=context,
                                  parameter_overrides=[Parameter('model_path', value=str(model))])
        try:
            extractor = features._extractor
            assert (extractor.rate_window_s, extractor.dt_s, extractor.edge_tolerance_m) == (
                0.02, 0.002, 0.005)
            assert predictor._monitor.predictor.dt_s == 0.002
            assert predictor._monitor.predictor.guard_com_height_m == 0.4
        finally:
            features.destroy_node()
            predictor.destroy_node()


@pytest.mark.parametrize('node_class, parameter, value', [
    (FeatureNode, 'rate_window_s', 0.02),
    (FeatureNode, 'edge_tolerance_m', 0.0),
    (FeatureNode, 'sample_period_s', 0.002),
    (PredictorNode, 'guard_com_height_m', 0.5),
    (PredictorNode, 'sample_period_s', 0.002),
])
def test_nodes_refuse_feature_settings_that_differ_from_the_models(tmp_path, node_class, parameter,
                                                                    value) -> None:
    model = write_momentum_model(tmp_path / 'model.json')       # the default settings
    with ros_context(DOMAIN) as context:
        with pytest.raises(NodeStartupError, match=f'{parameter} = {value} but model'):
            node_class(context=context, parameter_overrides=[
                Parameter('model_path', value=str(model)), Parameter(parameter, value=value)])
        # The same value as the model's is accepted.
        same = getattr(FeatureSettings(), parameter)
        node = node_class(context=context, parameter_overrides=[
            Parameter('model_path', value=str(model)), Parameter(parameter, value=same)])
        node.destroy_node()


def test_default_model_is_the_one_the_robot_profile_names_in_the_package_models_directory() -> None:
    assert default_model_path().parts[-2:] == ('models', 'default_model.json')
    assert default_model_path('g1').parts[-2:] == ('models', 'g1_attitude_model.json')
    assert default_model_path('g1').is_file()


def test_both_model_readers_find_the_robots_model_without_a_path_or_say_why(monkeypatch, tmp_path) -> None:
    """robot:=g1 and no model_path: the G1's model, not the default robot's; where that model is
    not installed: a start-up error naming it and what to do."""
    from fall_predictor.ros import share
    from fall_predictor.ros.feature_node import FeatureNode
    from fall_predictor.ros.predictor_node import THRESHOLD_FROM_MODEL, PredictorNode
    with ros_context(DOMAIN) as context:
        for node_class in (FeatureNode, PredictorNode):
            node = node_class(context=context, parameter_overrides=[Parameter('robot', value='g1')])
            node.destroy_node()
        # The G1's model is a boosted-trees model reading the base's attitude; the default
        # robot's is decision lists: the predictor took the G1's.
        for robot, boosted in (('g1', True), ('asimo_like', False)):
            node = PredictorNode(context=context, parameter_overrides=[Parameter('robot', value=robot)])
            threshold = node.get_parameter('decision_threshold').value
            assert (threshold != THRESHOLD_FROM_MODEL) == boosted, (robot, threshold)
            node.destroy_node()
        monkeypatch.setattr(share, 'package_share_dir', lambda: tmp_path)     # nothing installed
        for node_class in (FeatureNode, PredictorNode):
            with pytest.raises(NodeStartupError, match=r"robot 'g1' names the model "
                                                       r"g1_attitude_model.json, which is not shipped"):
                node_class(context=context, parameter_overrides=[Parameter('robot', value='g1')])


def test_predictor_process_refuses_to_start_with_a_clear_error(tmp_path: Path) -> None:
    """Missing, corrupt, FIFO, device, oversized model: exit code 2 (a mistake in a file, as
    the command line's); an invalid parameter: 1; each one FATAL line naming the problem, no
    traceback, no hang (processes started at once)."""
    good = write_momentum_model(tmp_path / 'good.json')
    corrupt = tmp_path / 'corrupt.json'
    corrupt.write_text(good.read_text()[:200])
    fifo = tmp_path / 'model.fifo'
    os.mkfifo(fifo)                     # opening it for reading used to block forever
    cases = {
        'missing': (['-p', f'model_path:={tmp_path / "missing.json"}'], 'missing.json'),
        'corrupt': (['-p', f'model_path:={corrupt}'], 'malformed or truncated JSON'),
        'bad tau_his': (['-p', f'model_path:={good}', '-p', 'tau_his_s:=5.0'], 'tau_his_s'),
        'fifo': (['-p', f'model_path:={fifo}'], 'not a regular file'),
        'device': (['-p', 'model_path:=/dev/zero'], 'not a regular file'),
        'too large': (['-p', f'model_path:={good}', '-p', 'max_model_bytes:=1000'],
                      'more than the limit of 1000 bytes'),
    }
    env = ros_environment(DOMAIN)
    processes = {
        name: subprocess.Popen(
            [sys.executable, '-m', 'fall_predictor.ros.predictor_node', '--ros-args', *args],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
        for name, (args, _) in cases.items()}
    for name, process in processes.items():
        output, _ = process.communicate(timeout=60)
        expected = cases[name][1]
        assert process.returncode == (1 if name == 'bad tau_his' else 2), (name, output)
        assert 'Traceback' not in output, (name, output)
        fatal = [line for line in output.splitlines() if '[FATAL]' in line]
        assert len(fatal) == 1 and 'cannot start' in fatal[0] and expected in fatal[0], output



def test_simulated_robot_closes_the_lock_step_loop_in_process() -> None:
    """simulator + controller in one process: every sample's command comes back in process
    (no missed or late command, no command subscription), and the world follows exactly the
    library's own simulation loop (the offline trajectory, bit for bit)."""
    duration_s = 0.6
    # Offline a little longer: the node steps in batches and may stop a few steps later.
    offline = {round(m.t * 1000): m for m in run_trajectory(
        None, duration_s + 0.02, stop_when_fallen=False).measurements}
    with ros_context(DOMAIN) as context:
        simulator, controller = [make() for make in robot_nodes(
            context=context, parameter_overrides=[
                Parameter('real_time_factor', value=0.0),
                Parameter('walk_duration_s', value=duration_s + 0.02 + 5.0)])]
        executor = SingleThreadedExecutor(context=context)
        for node in (simulator, controller):
            executor.add_node(node)
        try:
            assert not [s.topic_name for s in simulator.subscriptions
                        if s.topic_name.endswith('joint_commands')]
            steps = round(duration_s * 1000)
            assert spin_until(executor, lambda: simulator.counts['steps'] >= steps, 60.0)
            sim_t, sim_com = simulator._m.t, simulator._m.com.copy()
            counts = dict(simulator.counts)
        finally:
            executor.shutdown()
            for node in (controller, simulator):
                node.destroy_node()
    assert counts['missed_commands'] == 0 and counts['late_commands'] == 0
    assert counts['steps'] >= steps
    assert np.array_equal(sim_com, offline[round(sim_t * 1000)].com)


def test_a_node_refuses_a_profile_that_fails_its_static_checks_in_one_line(tmp_path: Path) -> None:
    """A team's profile whose mass is not its URDF's: the node exits 2 with one FATAL line naming
    the profile file, the field and the value to write (sim/checks.py), no traceback."""
    import shutil
    profiles = Path(__file__).resolve().parents[1] / 'fall_predictor' / 'profiles'
    shutil.copytree(profiles / 'g1_12dof', tmp_path / 'g1_12dof')
    profile = tmp_path / 'g1_12dof' / 'profile.yaml'
    profile.write_text(profile.read_text().replace('total_mass_kg: 32.106857', 'total_mass_kg: 60'))
    done = subprocess.run([sys.executable, '-m', 'fall_predictor.ros.predictor_node', '--ros-args',
                           '-p', f'robot:={profile}'], env=ros_environment(DOMAIN),
                          capture_output=True, text=True, timeout=60)
    output = done.stdout + done.stderr
    assert done.returncode == 2, output
    assert 'Traceback' not in output
    fatal = [line for line in output.splitlines() if '[FATAL]' in line]
    assert len(fatal) == 1 and str(profile) in fatal[0] and 'total_mass_kg' in fatal[0], output
    assert 'write total_mass_kg: 32.107' in fatal[0]
