"""In-process delivery between the nodes of one process (rclcpp's intra-process comms, by hand).

rclpy has no intra-process communication: a message between two nodes of one process goes
through DDS, (de)serialization and one more executor wake-up, which at 1 kHz cost more CPU
than a monitor node's own work. A node's main output is therefore an :class:`Output`, which
hands each sample to consumers of the same process before publishing it; a downstream node
built with ``upstream=<that output>`` (:func:`connect_input`) takes its input from there
instead of subscribing. ``fall_monitor`` and ``simulated_robot`` compose their nodes this way.

The monitor's outputs (measurements, features) hand over the decoded sample itself
(:meth:`Output.hand_off`): building a ROS message in Python and decoding it again cost more
than the estimator (a measurement: ~80 us to build, ~30 us to publish, ~45 us to decode), so
the message is built and published only while a subscriber of another process is matched (a
recorder, a tool); the consumer runs the same checks a decoded message passes.
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
    (de)serialization, while the topic keeps its publisher for recorders and tools.
    :meth:`hand_off` gives the consumers the decoded sample and builds the message only for
    subscribers of other processes. Consumers receive the very object that is handed over and
    must not modify it.
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

    def hand_off(self, sample: Any, build_msg: Callable[[], Any]) -> bool:
        """Hand the decoded ``sample`` to the in-process consumers, then, only if a subscriber
        of another process is matched, build its message (``build_msg()``) and publish it.
        Returns whether it was published. Consumers of an output must all take what it hands
        over: messages (:meth:`publish`) or decoded samples (this method), never both."""
        for consumer in self._consumers:
            consumer(sample)
        if self.publisher.get_subscription_count() == 0:
            return False
        self.publisher.publish(build_msg())
        return True


def connect_input(node: Node, msg_type: type, spec: TopicSpec, callback: Callable[[Any], None],
                  upstream: Optional[Output], lossless: bool = False,
                  take: Optional[Callable[[Any], None]] = None) -> list[Subscription]:
    """A node's main input: ``upstream``'s samples in process when given (to ``take``, which
    receives the decoded samples of an output that hands them off; else to ``callback``), else
    a subscription to ``callback`` (``lossless``: with the publisher's reliable QoS, see
    ``create_subscription``).

    Returns the subscriptions created (for :class:`Diagnostics`' ``unmatched_inputs``): none
    when the input comes from ``upstream``, whose topic must be ``spec``'s.
    """
    if upstream is None:
        return [create_subscription(node, msg_type, spec, callback, lossless=lossless)]
    take_from(node, spec, upstream, take or callback)
    return []


def take_from(node: Node, spec: TopicSpec, upstream: Output, callback: Callable[[Any], None]
              ) -> None:
    """Connect ``callback`` of ``node`` to ``upstream``, which must publish ``spec``'s topic
    as ``node`` resolves it (same namespace and remappings); ValueError otherwise."""
    expected = node.resolve_topic_name(spec.ros_name)
    if upstream.topic_name != expected:
        raise ValueError(f'in-process input {upstream.topic_name} is not {expected}')
    upstream.connect(callback)
