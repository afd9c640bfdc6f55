"""In-process delivery between the nodes of one process (rclcpp's intra-process comms, by hand).

rclpy has no intra-process communication: a message between two nodes of one process goes
through DDS, (de)serialization and one more executor wake-up, which at 1 kHz cost more CPU
than a monitor node's own work. A node's main output is therefore an :class:`Output`, which can
hand each message object to consumers of the same process before publishing it; a downstream
node built with ``upstream=<that output>`` (:func:`connect_input`) takes its input from there
instead of subscribing. ``fall_monitor`` and ``simulated_robot`` compose their nodes this way.
"""
from __future__ import annotations

from typing import Any, Callable, Optional

from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription

from fall_predictor.contract.topics import TopicSpec
from fall_predictor.ros.endpoints import create_subscription


class Output:
    """A node's main output: its publisher, plus consumers in the same process.

    :meth:`publish` first hands the message object to every connected consumer (the input
    callback of a downstream node of the same process, run at once, inside this callback), then
    publishes it over DDS for every other process. This is rclcpp's intra-process delivery done
    by hand for rclpy, which has none: a node composed with its consumer in one process
    (``fall_monitor``) saves the consumer's executor wake-up, the DDS round trip and the
    (de)serialization, while the topic keeps its publisher for recorders and tools. Consumers
    receive the very object that is published and must not modify it.
    """

    def __init__(self, publisher: Publisher) -> None:
        self.publisher = publisher
        self._consumers: list[Callable[[Any], None]] = []

    @property
    def topic_name(self) -> str:
        """The publisher's fully qualified topic name."""
        return self.publisher.topic_name

    @property
    def consumers(self) -> int:
        """How many in-process consumers are connected."""
        return len(self._consumers)

    def connect(self, consumer: Callable[[Any], None]) -> None:
        """Deliver every message published from now on to ``consumer`` as well."""
        self._consumers.append(consumer)

    def publish(self, msg: Any) -> None:
        """Hand ``msg`` to the in-process consumers, then publish it."""
        for consumer in self._consumers:
            consumer(msg)
        self.publisher.publish(msg)


def connect_input(node: Node, msg_type: type, spec: TopicSpec, callback: Callable[[Any], None],
                  upstream: Optional[Output], lossless: bool = False) -> list[Subscription]:
    """A node's main input: ``upstream``'s messages in process when given, else a subscription
    (``lossless``: with the publisher's reliable QoS, see ``create_subscription``).

    Returns the subscriptions created (for :class:`Diagnostics`' ``unmatched_inputs``): none
    when the input comes from ``upstream``, whose topic must be ``spec``'s.
    """
    if upstream is None:
        return [create_subscription(node, msg_type, spec, callback, lossless=lossless)]
    take_from(node, spec, upstream, callback)
    return []


def take_from(node: Node, spec: TopicSpec, upstream: Output, callback: Callable[[Any], None]
              ) -> None:
    """Connect ``callback`` of ``node`` to ``upstream``, which must publish ``spec``'s topic
    as ``node`` resolves it (same namespace and remappings); ValueError otherwise."""
    expected = node.resolve_topic_name(spec.ros_name)
    if upstream.topic_name != expected:
        raise ValueError(f'in-process input {upstream.topic_name} is not {expected}')
    upstream.connect(callback)
