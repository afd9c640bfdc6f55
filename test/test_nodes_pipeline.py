"""The five nodes as separate processes over real DDS: one scenario, several checks.

The module fixture ``system`` starts the recorder, predictor (hand-built momentum model),
feature, controller and simulator nodes (lock-step, as fast as possible) on a private ROS
domain with the package's :class:`~fall_predictor.ros.observer.Observer` as the tests' node,
and waits until they are connected. The fixture ``runs`` then drives two runs through the
simulator's ``~/reset``:

1. 10 s of walking without a push; at t = 5 s the predictor's ``tau_his_s`` is changed from
   the model's 0.01 s to 0.05 s at run time; at t = 3 s malformed joint commands and push
   requests are sent to the simulator;
2. a fresh world pushed sideways with 450 N for 0.1 s at t = 2.5 s (offline, under C_bal
   throughout, this push makes the robot fall at t = 3.55 s), followed for 1.5 s.

Then the simulator is paused, and the later tests inject malformed messages, let the inputs
go stale, and finally stop everything and compare the bags with what the nodes published.

The fixtures check nothing: they record what was received and acknowledged, and each check is
made by the test named after it, so one failing check fails one test. They raise
:class:`SystemNotRunning` only when the system cannot be driven at all (a node died, the nodes
never connected, a run stopped advancing). The tests of this module share that live system
and run in file order.
"""
from __future__ import annotations

import math
import time
from collections.abc import Iterator

import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped
from sensor_msgs.msg import JointState
from pipeline_support import (CONNECT_TIMEOUT_S, Runs, System, SystemNotRunning, check_alive,
                              dead_nodes, follow, run, start_nodes)
from test_nodes_support import MODEL_TAU_HIS_S, ros_context, test_domain_id

from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.data.bagio import iter_messages, read_trajectory
from fall_predictor.ros.bringup import NodeProcess, stop_nodes
from fall_predictor.monitor.features import extract_features
from fall_predictor.ros.endpoints import create_publisher
from fall_predictor.ros.health import UNMATCHED_INPUTS
from fall_predictor.ros.observer import Observer, ObservedState
from fall_predictor.monitor.records import Measurement, PushSpec
from fall_predictor.contract import messages
from fall_predictor.contract.topics import (CONTROLLER_MODE, FALL_DIRECTION, FALL_EVENT, FALLING,
                                            FEATURES, JOINT_COMMANDS, JOINT_STATES, MEASUREMENT,
                                            PUSH, STATE)
from fall_predictor.contract.wire import LEVEL_STALE
from fall_predictor.monitor.fall_monitor import STATUS_OK, STATUS_STALE
from fall_predictor.msg import Features
from fall_predictor.msg import Measurement as MeasurementMsg

STRONG_PUSH = PushSpec(force_n=450.0, angle_deg=90.0, height_m=0.1, t_push=2.5)
NO_PUSH_RUN_S = 10.0
SIM_DT_S = 0.001                    #: the simulator's step: one measurement each [s]
GARBAGE_AT_S = 3.0                  #: malformed commands sent when the observer sees this [s]
TAU_HIS_CHANGE_AT_S = 5.0           #: requested when the observer sees this sample time [s]
NEW_TAU_HIS_S = 0.05
FOLLOW_AFTER_PUSH_S = 1.5


def _send_bad_commands_and_push_requests(observer: Observer) -> bool:
    """Send malformed joint commands and push requests; whether the commands were matched."""
    node = observer.node
    commands = create_publisher(node, JointState, JOINT_COMMANDS)
    # Matched with the simulator and the recorder.
    matched = observer.spin_until(lambda: commands.get_subscription_count() >= 2, 10.0)
    wrong_names = ros_qos.joint_state_to_msg(ros_qos.sim_ns(observer.t_last),
                                             [f'j{i}' for i in range(26)], np.zeros(26))
    nan_command = ros_qos.joint_state_to_msg(ros_qos.sim_ns(observer.t_last), rm.JOINT_NAMES,
                                             np.zeros(26))
    nan_command.position[3] = math.nan
    commands.publish(wrong_names)
    commands.publish(nan_command)
    vertical, bad_frame, bad_torque = WrenchStamped(), WrenchStamped(), WrenchStamped()
    vertical.wrench.force.z = 100.0
    bad_frame.header.frame_id = 'world'
    bad_frame.wrench.force.x = 100.0
    bad_torque.wrench.force.x = 100.0
    bad_torque.wrench.torque.z = 5.0
    for msg in (vertical, bad_frame, bad_torque):
        observer.push_pub.publish(msg)
    # The publisher stays (the node keeps it): destroying it could discard what is not
    # acknowledged yet, and waiting for the acknowledgements would stop the observer from
    # taking its states for up to a DDS heartbeat period (3 s).
    return matched


@pytest.fixture(scope='module')
def system(tmp_path_factory: pytest.TempPathFactory) -> Iterator[System]:
    """The five nodes started and connected with the tests' observer; nothing run yet."""
    tmp = tmp_path_factory.mktemp('nodes')
    domain = test_domain_id(0)
    nodes: dict[str, NodeProcess] = {}
    with ros_context(domain) as context:
        observer = Observer(context, 'test_observer')
        try:
            start_nodes(tmp, domain, nodes)
            if not observer.spin_until(lambda: observer.connected(nodes.keys()), CONNECT_TIMEOUT_S,
                                       lambda: check_alive(nodes)):
                unmatched = {name: status.values.get(UNMATCHED_INPUTS)
                             for name, status in observer.diagnostics.items()}
                raise SystemNotRunning(f'the nodes did not connect within {CONNECT_TIMEOUT_S} s '
                                       f'(unmatched inputs: {unmatched}; logs in {tmp})')
            yield System(observer, nodes, tmp)
        finally:
            observer.destroy()
            stop_nodes(nodes)


@pytest.fixture(scope='module')
def runs(system: System) -> Runs:
    """The two runs of the module docstring, then the simulator paused."""
    observer, nodes = system.observer, system.nodes

    # Run 1: walking, no push; tau_his changed at run time; garbage to the simulator.
    observer.reset_world()
    follow(observer, nodes, GARBAGE_AT_S)
    bad_commands_matched = _send_bad_commands_and_push_requests(observer)
    follow(observer, nodes, TAU_HIS_CHANGE_AT_S)
    tau_his_change = observer.set_parameters('predictor_node', tau_his_s=NEW_TAU_HIS_S)
    t_tau_his_set = observer.t_last
    no_push = run(observer, nodes, NO_PUSH_RUN_S)

    # Run 2: a fresh world and a strong sideways push.
    observer.reset_world()
    observer.request_push(STRONG_PUSH)
    strong_push = run(observer, nodes, STRONG_PUSH.t_force_end + FOLLOW_AFTER_PUSH_S)
    check_alive(nodes)
    return Runs(no_push, strong_push, tau_his_change, t_tau_his_set, bad_commands_matched)


def test_no_push_gives_no_trigger_for_10_s(system: System, runs: Runs) -> None:
    run = runs.no_push
    assert run.samples[-1][0] >= NO_PUSH_RUN_S
    assert [t for t, _ in run.samples[:3]] == [0.0, 0.001, 0.002]
    assert run.t_fallen is None
    assert not any(s.falling or s.atomic or s.latched for s in run.states)
    assert {mode for _, mode in run.modes} <= {'balance'}
    # One state per sample, stamped with its sample's own stamp: predicted (OK), or STALE when
    # it arrived too late. The monitor reads best effort (REP 2003), so a saturated machine may
    # lose samples, never silently: every sample up to the predictor's last one has a state
    # published or is a gap in the features it received (lost before the feature node, or
    # between the two), counted exactly. The reference is the simulator's 1 kHz grid, and the
    # predictor's own count of the states it published: this test's subscriptions lose some
    # on a loaded machine too (its observer follows every 1 kHz stream), no fault of the monitor.
    predictor = run.counters['predictor_node']
    samples = round(int(predictor['stamp_ns']) * 1e-9 / SIM_DT_S) + 1
    assert int(predictor['states']) + int(predictor['missing_samples']) == samples, predictor
    ts = [s.t for s in run.states]
    assert ts == sorted(set(ts))
    assert {s.status for s in run.states} <= {STATUS_OK, STATUS_STALE}
    steps = round(run.samples[-1][0] / SIM_DT_S)
    grid = {round(k * SIM_DT_S, 6) for k in range(steps + 1)}
    assert {round(t, 6) for t in ts} <= grid
    assert ts                                       # (how many are lost under load: benchmarks)


def test_simulator_survived_malformed_commands_and_push_requests(system: System,
                                                                  runs: Runs) -> None:
    # The garbage of run 1 (t = 3 s) was rejected and counted; run 1 went on to 10 s.
    assert runs.bad_commands_matched, 'malformed commands not matched with simulator and recorder'
    status = system.observer.diagnostics['/simulator_node']
    assert int(status.values['invalid_commands']) >= 1       # wrong names
    assert int(status.values['push_requests_rejected']) == 3
    assert int(status.values['pushes']) == 1                 # only the strong push


def test_tau_his_change_takes_effect_while_running(runs: Runs) -> None:
    accepted = runs.tau_his_change[0]
    assert accepted.successful, accepted.reason
    run1, run2 = runs.no_push, runs.strong_push
    # One switch, in sample order, from the model's window to the new one; every sample
    # after the change was acknowledged (the predictor lags the simulator) has the new one.
    taus = [s.tau_his_s for s in run1.states]
    switch = taus.index(NEW_TAU_HIS_S)
    assert set(taus[:switch]) == {MODEL_TAU_HIS_S} and set(taus[switch:]) == {NEW_TAU_HIS_S}
    # The observer's notion of "now" lags the predictor by up to ~1.4 s on a saturated
    # 2-core machine (benchmarks/bench_latency.py), hence the generous upper bound.
    assert 1.0 < run1.states[switch].t < runs.t_tau_his_set + 1.5
    # The new window decides the trigger: falling exactly 50 ms into the atomic run.
    first_atomic = next(s for s in run2.states if s.atomic and s.t >= STRONG_PUSH.t_push)
    first_falling = next(s for s in run2.states if s.falling)
    window = [s for s in run2.states if first_atomic.t <= s.t <= first_falling.t]
    assert all(s.atomic for s in window)
    assert first_falling.t - first_atomic.t >= NEW_TAU_HIS_S - 1e-6
    # Exactly 50 ms when every state of the run reached the observer (on a saturated machine
    # the monitor may lose samples, counted; a lost non-atomic one hides where the run began).
    if len(window) == round((first_falling.t - first_atomic.t) * 1000) + 1:
        assert first_falling.t - first_atomic.t == pytest.approx(NEW_TAU_HIS_S, abs=1e-6)


def test_strong_push_is_predicted_before_fallen_and_controller_switches_for_good(
        system: System, runs: Runs) -> None:
    run = runs.strong_push
    predicted = next((s for s in run.states if s.falling), None)
    assert predicted is not None, 'the strong push was not predicted'
    assert STRONG_PUSH.t_push <= predicted.t < STRONG_PUSH.t_force_end + 0.2
    assert predicted.atomic and not predicted.guard           # the decision list, not the guard
    if run.t_fallen is not None:                              # C_fall may keep it up
        assert predicted.t < run.t_fallen
    modes = [mode for _, mode in run.modes]
    assert 'fall' in modes
    assert 'balance' not in modes[modes.index('fall'):]        # one-way
    assert all(s.latched for s in run.states if s.t >= predicted.t)
    status = system.observer.fresh_diagnostics('controller_node')
    assert status.values['mode'] == 'fall'
    # The switch answers the trigger: from the switch on, every state says latched (the first
    # falling state this test received may come after it: its subscription loses some under load).
    t_switch = float(status.values['t_switch_s'])
    assert STRONG_PUSH.t_push <= t_switch
    assert all(s.latched for s in run.states if s.t >= t_switch)


@pytest.mark.usefixtures('runs')                # after the runs, the simulator paused
def test_invalid_parameters_are_rejected_with_a_reason(system: System) -> None:
    observer = system.observer
    out_of_range = {'predictor_node': {'tau_his_s': -0.5},
                    'simulator_node': {'real_time_factor': -1.0},
                    'feature_node': {'stale_timeout_s': 0.0}}
    read_only = {'predictor_node': {'model_path': '/elsewhere.json'},
                 'simulator_node': {'lockstep': False},
                 'controller_node': {'walk_duration_s': 10.0}}
    for node, values in out_of_range.items():
        result = observer.set_parameters(node, **values)[0]
        assert not result.successful and 'range' in result.reason, (node, result.reason)
    for node, values in read_only.items():
        result = observer.set_parameters(node, **values)[0]
        assert not result.successful and 'read-only' in result.reason, (node, result.reason)
    result = observer.set_parameters('predictor_node', tau_his_s='long')[0]
    assert not result.successful and 'type' in result.reason, result.reason
    assert observer.set_parameters('simulator_node', command_timeout_s=0.25)[0].successful
    assert observer.fresh_diagnostics('predictor_node').values['tau_his_s'] == str(NEW_TAU_HIS_S)
    assert dead_nodes(system.nodes) == ''


@pytest.mark.usefixtures('runs')
def test_bad_input_does_not_kill_any_node_and_gives_degraded_state(system: System) -> None:
    observer = system.observer
    types = ros_qos.TYPES

    def measurement(**change) -> MeasurementMsg:
        msg = messages.measurement_msg(types, 50_000_000_000, 'odom', _fake_measurement())
        for path, value in change.items():
            obj, field = msg, path.split('__')
            for name in field[:-1]:
                obj = getattr(obj, name)
            setattr(obj, field[-1], value)
        return msg
    # Well-formed messages whose values no robot produces (each would have killed or fooled a
    # node before): NaN CoM, infinite momentum, a CoP 1e154 m away, a CoM 5 m above the ground.
    bad_measurements = [measurement(com__x=math.nan), measurement(linear_momentum__y=math.inf),
                        measurement(cop__x=1.3e154), measurement(com__z=5.0)]
    good_features = messages.features_msg(types, 4_200_000_000, np.zeros(15), 0)

    def features(**change) -> Features:
        msg = messages.features_msg(types, 4_200_000_000, np.zeros(15), 0)
        for name, value in change.items():
            setattr(msg, name, value)
        return msg
    nan_features = np.zeros(15)
    nan_features[3] = math.nan
    bad_features = [features(features=nan_features), features(contact_mode=99),
                    features(base_tilt=-1.0), features(features=np.full(15, math.inf))]
    assert good_features.fault == ''
    measurement_pub = create_publisher(observer.node, MeasurementMsg, MEASUREMENT)
    features_pub = create_publisher(observer.node, Features, FEATURES)
    assert observer.spin_until(lambda: measurement_pub.get_subscription_count() >= 3
                            and features_pub.get_subscription_count() >= 2, 10.0)

    def invalid_counts() -> tuple[int, int, int]:
        """Invalid inputs counted by the feature, controller and predictor nodes."""
        return (int(observer.fresh_diagnostics('feature_node').values['invalid_measurements']),
                int(observer.fresh_diagnostics('controller_node').values['invalid_inputs']),
                int(observer.fresh_diagnostics('predictor_node').values['invalid_features']))

    # A best-effort subscriber drops what arrives before it has matched the publisher, and the
    # publisher's match count says nothing about the subscriber's side (discovery is slower on
    # a loaded machine): send one bad message of each kind until every receiving node has
    # counted one, so that the batch below goes over matched links.
    deadline = time.monotonic() + 30.0
    base = invalid_counts()
    while min(base) < 1:
        assert time.monotonic() < deadline, f'bad inputs never counted: {base}'
        measurement_pub.publish(bad_measurements[0])
        features_pub.publish(bad_features[0])
        base = invalid_counts()
    observer.spin_until(lambda: False, 0.5)         # let the priming messages' last copies land
    base = invalid_counts()
    observer.states.clear()
    for msg in bad_measurements:
        measurement_pub.publish(msg)
    for msg in bad_features:
        features_pub.publish(msg)

    def degraded() -> list[ObservedState]:
        return [s for s in observer.states if s.status == STATUS_STALE]

    assert observer.spin_until(lambda: len(degraded()) >= len(bad_features), 10.0), observer.states
    assert all(not s.falling for s in degraded())
    # Every bad message is counted once, by each node that reads its topic, and no more.
    expected = (base[0] + len(bad_measurements), base[1] + len(bad_measurements),
                base[2] + len(bad_features))
    counted = invalid_counts()
    while counted != expected and time.monotonic() < deadline + 10.0 and all(
            c <= e for c, e in zip(counted, expected)):
        counted = invalid_counts()
    assert counted == expected, (counted, expected)
    assert dead_nodes(system.nodes) == ''


def _fake_measurement() -> Measurement:
    return Measurement(t=50.0, com=np.array([0.0, 0.0, 0.59]), lin_mom=np.zeros(3),
                       ang_mom=np.zeros(3), heading=0.0, cop=np.zeros(3),
                       left_contacts=np.zeros((1, 3)), right_contacts=np.zeros((0, 3)),
                       left_foot=np.zeros(3), right_foot=np.zeros(3), non_foot_contact=False)


@pytest.mark.usefixtures('runs')
def test_stale_inputs_give_stale_state_and_diagnostics(system: System) -> None:
    observer = system.observer
    result = observer.set_parameters('predictor_node', stale_timeout_s=0.3)[0]
    assert result.successful
    observer.states.clear()
    assert observer.spin_until(lambda: any(s.status == STATUS_STALE for s in observer.states),
                               5.0)
    stale = [s for s in observer.states if s.status == STATUS_STALE]
    assert all(not s.falling for s in stale)
    predictor_status = observer.fresh_diagnostics('predictor_node')
    assert predictor_status.level == LEVEL_STALE
    assert predictor_status.message.startswith('no features for')
    assert observer.fresh_diagnostics('feature_node').level == LEVEL_STALE


@pytest.mark.usefixtures('runs')
def test_recorder_bags_hold_every_published_message(system: System) -> None:
    observer = system.observer
    nodes = system.nodes
    # No more STALE states from now on, so that the counts below are final.
    assert observer.set_parameters('predictor_node', stale_timeout_s=60.0)[0].successful
    final = {name: observer.fresh_diagnostics(name).values
             for name in ('simulator_node', 'controller_node', 'feature_node', 'predictor_node')}
    simulator = final['simulator_node']
    codes = stop_nodes(nodes)
    assert all(code == 0 for code in codes.values()), (
        codes, {name: nodes[name].log_tail(60) for name, code in codes.items() if code != 0})
    published = {
        MEASUREMENT.name: int(simulator['measurements']),
        JOINT_STATES.name: int(simulator['joint_states']),
        PUSH.name: int(simulator['pushes']),
        # + the observer's wrong-names command: valid on the wire, rejected by the simulator only.
        JOINT_COMMANDS.name: int(final['controller_node']['commands']) + 1,
        CONTROLLER_MODE.name: int(final['controller_node']['modes']),
        FEATURES.name: int(final['feature_node']['features']) + int(final['feature_node']['faults']),
        STATE.name: int(final['predictor_node']['states']),
        FALL_DIRECTION.name: int(final['predictor_node']['direction_messages']),
    }
    bags = sorted((system.tmp / 'bags').glob('run_*'))
    assert [b.name for b in bags] == ['run_000', 'run_001']
    in_bags = dict.fromkeys([*published, FALLING.name, FALL_EVENT.name], 0)
    for bag in bags:
        for message in iter_messages(bag):
            in_bags[message.topic] += 1
    # The trigger is latched (depth 1): a recorder that joins late gets the current value only.
    trigger_messages = int(final['predictor_node']['trigger_messages'])
    assert 1 <= in_bags.pop(FALLING.name) <= trigger_messages
    assert 1 <= in_bags.pop(FALL_EVENT.name) <= int(final['predictor_node']['events'])
    assert in_bags == published

    recorded_runs = [read_trajectory(bag) for bag in bags]
    for recorded in recorded_runs:
        # What the dataset code does with a bag: features from the measurements.
        X, mode = extract_features(recorded.measurements, attitude=True)   # as the node does
        offline = {m.t: (X[i], mode[i]) for i, m in enumerate(recorded.measurements)}
        # The feature node reads best effort: under load it may skip a sample (counted as
        # missing); each feature it did publish is what the offline code computes... after
        # a skipped sample its rate window differs, so compare the samples after a run of
        # 10 consecutive ones.
        live_ts = [f.t for f in recorded.features]
        assert len(live_ts) >= 0.5 * len(recorded.measurements)
        consecutive = 0
        for k, f in enumerate(recorded.features):
            consecutive = consecutive + 1 if k and round((f.t - live_ts[k - 1]) * 1e3) == 1 else 0
            if consecutive >= 10:
                # (Live, times are run times from the first sample: equal up to round-off.)
                assert np.allclose(f.x, offline[f.t][0], rtol=1e-9, atol=1e-9)
                assert f.mode == offline[f.t][1]
    assert recorded_runs[0].measurements[-1].t >= NO_PUSH_RUN_S
    assert len(recorded_runs[1].pushes) == 1 and recorded_runs[1].pushes[0].t == STRONG_PUSH.t_push
    # After the switch, C_fall holds one pose.
    t_switch = float(observer.diagnostics['/controller_node'].values['t_switch_s'])
    frozen = [m.msg.position for m in iter_messages(bags[1], [JOINT_COMMANDS.name])
              if m.t_ns > round(t_switch * 1e9)]
    assert frozen and all(np.array_equal(q, frozen[0]) for q in frozen)
