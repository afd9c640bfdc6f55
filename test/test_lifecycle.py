"""ros/lifecycle.py: the monitor's nodes are managed (lifecycle) nodes: a model loaded at
configure, inputs acted on only while active, and a node that cannot configure says why."""
from __future__ import annotations

import numpy as np
import rclpy.node
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from test_nodes_support import MODEL_TAU_HIS_S, ros_context, test_domain_id, write_momentum_model

from fall_predictor.contract import messages
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.endpoints import create_subscription
from fall_predictor.ros.predictor_node import PredictorNode
from fall_predictor.ros.runner import spin_until

DOMAIN = test_domain_id(76)


def test_a_managed_predictor_waits_loads_at_configure_and_triggers_only_when_active(tmp_path):
    from std_msgs.msg import Bool

    from fall_predictor.contract.topics import FALLING

    model = write_momentum_model(tmp_path / 'model.json')
    with ros_context(DOMAIN) as context:
        node = PredictorNode(context=context, parameter_overrides=[
            Parameter('model_path', value=str(model)), Parameter('autostart', value=False),
            Parameter('max_sample_age_s', value=0.0)])     # stamps near 1970: no age check
        probe = rclpy.node.Node('lifecycle_probe', context=context)
        trigger: list[bool] = []
        create_subscription(probe, Bool, FALLING, lambda m: trigger.append(m.data))
        executor = SingleThreadedExecutor(context=context)
        for n in (node, probe):
            executor.add_node(n)

        def feed(p_x: float, start_ns: int) -> None:
            for k in range(30):
                x = np.zeros(15)
                x[2], x[3] = 0.59, p_x
                node._on_features(messages.features_msg(ros_qos.TYPES, start_ns + k * 1_000_000,
                                                        x, 0))
        try:
            assert node._state_machine.current_state[1] == 'unconfigured'
            assert node._monitor is None                    # the model is not loaded yet
            assert node.get_parameter('tau_his_s').value == -1.0
            node.trigger_configure()
            assert node._state_machine.current_state[1] == 'inactive'
            assert node.get_parameter('tau_his_s').value == MODEL_TAU_HIS_S
            feed(40.0, 1_000_000_000)                       # inactive: inputs ignored
            assert node.counts['features'] == 0 and not node._monitor.latched
            node.trigger_activate()
            # This node's publisher (another participant of the domain may publish the topic too).
            assert spin_until(executor, lambda: any(
                info.node_name == 'predictor_node'
                for info in probe.get_publishers_info_by_topic(FALLING.ros_name)), 5.0)
            feed(40.0, 2_000_000_000)
            assert node._monitor.latched and node.counts['falling_states'] > 0
            assert spin_until(executor, lambda: trigger[-1:] == [True], 5.0)
            node.trigger_deactivate()                       # the trigger stays: no reset
            node.trigger_activate()
            spin_until(executor, lambda: False, 0.3)
            assert trigger[-1] is True and False not in trigger[trigger.index(True):]
            assert node._monitor.latched
        finally:
            executor.shutdown()
            node.destroy_node()
            probe.destroy_node()


def test_only_the_reset_undoes_a_fall_whatever_the_lifecycle_or_the_enable_switch(tmp_path):
    """deactivate/activate, cleanup/configure (the model read again) and enable false/true all
    keep the latch; `falling` turns false only after a RESET event, stamped with the last sample;
    the model's window (-1) is refused while running, in words."""
    from std_msgs.msg import Bool
    from std_srvs.srv import SetBool, Trigger

    from fall_predictor.contract.topics import FALL_EVENT, FALLING
    from fall_predictor.monitor.fall_monitor import EVENT_FALLING, EVENT_RESET, STATUS_DISABLED
    from fall_predictor.msg import FallEvent

    model = write_momentum_model(tmp_path / 'model.json')
    with ros_context(DOMAIN) as context:
        node = PredictorNode(context=context, parameter_overrides=[
            Parameter('model_path', value=str(model)), Parameter('max_sample_age_s', value=0.0)])
        probe = rclpy.node.Node('latch_probe', context=context)
        seen: list[tuple[str, object]] = []
        create_subscription(probe, Bool, FALLING, lambda m: seen.append(('falling', m.data)))
        create_subscription(probe, FallEvent, FALL_EVENT, lambda m: seen.append(
            ('event', (m.event, m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec))))
        executor = SingleThreadedExecutor(context=context)
        for n in (node, probe):
            executor.add_node(n)

        def feed(p_x: float, start_ns: int) -> None:
            for k in range(30):
                x = np.zeros(15)
                x[2], x[3] = 0.59, p_x
                node._on_features(messages.features_msg(ros_qos.TYPES, start_ns + k * 1_000_000,
                                                        x, 0))
        try:
            assert spin_until(executor, lambda: ('falling', False) in seen, 5.0)
            feed(40.0, 2_000_000_000)
            assert spin_until(executor, lambda: ('falling', True) in seen, 5.0)
            result = node.set_parameters([Parameter('tau_his_s', value=-1.0)])[0]
            assert not result.successful and 'taken at configure only' in result.reason
            assert node._monitor.tau_his_s == MODEL_TAU_HIS_S
            for change in ('deactivate/activate', 'cleanup/configure', 'enable false/true'):
                if change == 'deactivate/activate':
                    node.trigger_deactivate()
                    node.trigger_activate()
                elif change == 'cleanup/configure':
                    node.trigger_deactivate()
                    node.trigger_cleanup()
                    node.trigger_configure()
                    node.trigger_activate()
                else:
                    off = node._on_enable(SetBool.Request(data=False), SetBool.Response())
                    assert 'stays until' in off.message
                    feed(0.0, 2_100_000_000)                # disabled: says so, still latched
                    assert node.counts['states'] and node._monitor.latched
                    node._on_enable(SetBool.Request(data=True), SetBool.Response())
                assert node._monitor.latched, change
            spin_until(executor, lambda: False, 0.3)
            assert [v for k, v in seen if k == 'falling'] in ([False, True], [False, True, True]), seen
            done = node._on_reset(Trigger.Request(), Trigger.Response())
            assert done.success and not node._monitor.latched
            # The RESET event (published before `falling` turns false: two topics, so a
            # subscriber may take them in either order), stamped with the last sample's stamp.
            assert spin_until(executor, lambda: len([k for k, _ in seen if k == 'event']) == 2
                              and seen.count(('falling', False)) == 2, 5.0)
            events = [v for k, v in seen if k == 'event']
            assert events == [(EVENT_FALLING, 2_000_000_000 + 10 * 1_000_000),
                              (EVENT_RESET, 2_100_000_000 + 29 * 1_000_000)], events
            assert node._monitor.unusable('x').status != STATUS_DISABLED
        finally:
            executor.shutdown()
            node.destroy_node()
            probe.destroy_node()


def test_a_managed_node_that_cannot_configure_says_why_and_stays_unconfigured(tmp_path):
    with ros_context(DOMAIN) as context:
        node = PredictorNode(context=context, parameter_overrides=[
            Parameter('model_path', value=str(tmp_path / 'missing.json')),
            Parameter('autostart', value=False)])
        try:
            node.trigger_configure()
            assert node._state_machine.current_state[1] == 'unconfigured'
            assert 'no usable model' in str(node.startup_error)
        finally:
            node.destroy_node()
