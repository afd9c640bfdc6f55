"""Publishers and subscriptions on the topics of the contract (:mod:`fall_predictor.contract.topics`),
with its QoS, overridable by parameters."""
from __future__ import annotations

from typing import Any, Callable, Optional

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos_overriding_options import QoSOverridingOptions
from rclpy.subscription import Subscription

from fall_predictor.contract.topics import TopicSpec
from fall_predictor.ros import conversions as ros_qos


def create_publisher(node: Node, msg_type: type, spec: TopicSpec) -> Publisher:
    """A publisher on ``spec``'s topic (relative name) with its wire QoS.

    The QoS can be overridden by parameters (``qos_overrides.<topic>.publisher.<policy>``,
    rclpy's ``QoSOverridingOptions``). Without rclpy's default QoS-event handlers (incompatible
    QoS / type warnings): each one is a waitable that the executor polls on every wake-up, a
    measurable cost at 1 kHz, and the QoS of every topic comes from
    :mod:`fall_predictor.contract.topics`, so they cannot disagree.
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
