"""ros/in_process.py: an output hands its consumers the decoded sample and builds the message
only for subscribers of other processes."""
from __future__ import annotations

from fall_predictor.ros.in_process import Output


class _Publisher:
    def __init__(self, subscribers: int) -> None:
        self.subscribers = subscribers
        self.published: list[object] = []
        self.topic_name = '/fall_predictor/measurement'

    def get_subscription_count(self) -> int:
        return self.subscribers

    def publish(self, msg: object) -> None:
        self.published.append(msg)


def test_hand_off_builds_no_message_without_a_subscriber_of_another_process() -> None:
    publisher = _Publisher(subscribers=0)
    output = Output(publisher)
    taken: list[object] = []
    output.connect(taken.append)
    built: list[int] = []

    def build() -> str:
        built.append(1)
        return 'message'
    assert output.hand_off('sample', build) is False
    assert taken == ['sample'] and built == [] and publisher.published == []


def test_hand_off_builds_and_publishes_once_a_subscriber_is_matched() -> None:
    publisher = _Publisher(subscribers=1)
    output = Output(publisher)
    order: list[str] = []
    output.connect(lambda sample: order.append(f'consumer {sample}'))
    assert output.hand_off('sample', lambda: order.append('built') or 'message') is True
    assert order == ['consumer sample', 'built']       # consumers first, as publish() does
    assert publisher.published == ['message']
