"""A recorder SIGKILLed mid-run over DDS: ``repair-bag`` gives back what reached its file.

The recorder (one part per run, ``split_duration_s:=0``) receives 5 s of 1 kHz measurements
and is killed once its diagnostics say it wrote all it received. Its bag has no
``metadata.yaml`` and no MCAP summary, so no reader opens it. After ``fall-predictor
repair-bag`` the package's reader opens the run, and the measurements in it are ones
published, in order, none invented; at least one 1 MiB chunk (~2600 of these messages) had
reached the file, the rest was still in the writer's memory.
"""
from __future__ import annotations

import json
import os
import signal
import sys
import time
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from fall_predictor.cli import main
from fall_predictor.data.bagio import BagError, bag_parts, read_trajectory
from fall_predictor.contract.topics import MEASUREMENT
from fall_predictor.msg import Measurement as MeasurementMsg
from fall_predictor.ros.bringup import ros_environment, start_process
from fall_predictor.ros.endpoints import create_publisher
from test_nodes_support import ros_context, test_domain_id
from test_recorder_crash import measurement_msg

SECONDS = 5.0


def test_repair_bag_recovers_the_open_bag_of_a_killed_recorder(tmp_path: Path, capsys) -> None:
    domain = test_domain_id(121)
    bags = tmp_path / 'bags'
    recorder = start_process('recorder_node', [
        sys.executable, '-m', 'fall_predictor.ros.recorder_node', '--ros-args',
        '-p', f'bag_path:={bags}', '-p', 'split_duration_s:=0.0',
        '-p', 'start_type_description_service:=false'], ros_environment(domain), tmp_path)
    written: list[str] = []
    sent: list[float] = []
    try:
        with ros_context(domain) as context:
            node = Node('robot', context=context)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            publisher = create_publisher(node, MeasurementMsg, MEASUREMENT)
            key = f'{MEASUREMENT.name} received/written/rejected'
            node.create_subscription(
                DiagnosticArray, '/diagnostics',
                lambda msg: written.extend(kv.value for s in msg.status for kv in s.values
                                           if s.name == '/recorder_node' and kv.key == key), 50)
            deadline = time.monotonic() + 60.0
            while publisher.get_subscription_count() < 1:
                assert time.monotonic() < deadline, recorder.log_tail()
                executor.spin_once(timeout_sec=0.05)
            start = time.monotonic()
            for k in range(round(SECONDS * 1000)):
                t = round(k * 0.001, 3)
                while time.monotonic() < start + t:
                    executor.spin_once(timeout_sec=0.0005)
                publisher.publish(measurement_msg(t))
                sent.append(t)
            # Kill once two reports after the last publish agree (all received is written).
            reports = len(written)
            deadline = time.monotonic() + 20.0
            while not (len(written) >= reports + 2 and written[-1] == written[-2]):
                assert time.monotonic() < deadline, (written[-3:], recorder.log_tail())
                executor.spin_once(timeout_sec=0.05)
            os.kill(recorder.process.pid, signal.SIGKILL)
            recorder.process.wait(timeout=10)
            node.destroy_node()
    finally:
        if recorder.process.poll() is None:
            recorder.process.kill()
    assert recorder.process.returncode == -signal.SIGKILL
    run = bags / 'run_000'
    part = run / 'part_000'
    assert not (part / 'metadata.yaml').exists()
    with pytest.warns(UserWarning, match='unfinished part'), pytest.raises(BagError):
        read_trajectory(run)

    assert main(['repair-bag', str(bags), '--json']) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary['repaired'] == 1 and summary['bags'] == 1
    assert bag_parts(run) == [part]
    times = [m.t for m in read_trajectory(run).measurements]
    assert summary['messages_recovered'] == {MEASUREMENT.name: len(times)}
    received, n_written, rejected = map(int, written[-1].split('/'))
    assert n_written == received >= 3000 and rejected == 0
    # What was published, in order, none invented; a 1 MiB chunk (~2650 of them) reached the
    # file, what the writer still held in memory (less than a chunk) did not.
    assert times == sorted(set(times)) and set(times) <= set(sent)
    assert 2000 <= len(times) <= n_written
    assert (part / f'{part.name}.mcap.damaged').exists()
