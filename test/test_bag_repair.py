"""``repair-bag``: an interrupted MCAP bag gives back every complete message.

Known answers: the messages are written by :class:`BagWriter` from a deterministic sequence
(message k is the measurement at t = k ms with CoM x = 0.1 mm times k mod 5000), so the recovered bag must hold an
exact prefix of that sequence. The lower bound on its length comes from rosbags' own summary
index of the intact file (its chunk offsets and message counts), independent of the scanner:
every message of a chunk lying wholly before the cut must come back.
"""
from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import Reader
from rosbags.rosbag2.storage_mcap import McapReader

from fall_predictor.cli import main
from fall_predictor.data.bag_repair import BACKUP_SUFFIX, repair_bag
from fall_predictor.data.bag_writer import BagWriter
from fall_predictor.data.bagio import BagError, bag_parts, iter_messages, read_trajectory
from fall_predictor.contract.topics import FEATURES, MEASUREMENT
from fall_predictor.monitor.records import Measurement


def measurement(k: int) -> Measurement:
    feet = np.array([[0.1, 0.1, 200.0], [-0.1, 0.1, 200.0], [-0.1, -0.1, 200.0], [0.1, -0.1, 200.0]])
    return Measurement(t=0.001 * k, com=np.array([1e-4 * (k % 5000), 0.0, 0.59]), lin_mom=np.zeros(3),
                       ang_mom=np.zeros(3), heading=0.0, cop=np.zeros(3),
                       left_contacts=feet[:2], right_contacts=feet[2:],
                       left_foot=np.array([0.0, 0.1, 0.0]), right_foot=np.array([0.0, -0.1, 0.0]),
                       non_foot_contact=False)


def assert_prefix(bag: Path) -> int:
    """The bag's measurements are exactly measurements 0..M-1; returns M."""
    measurements = read_trajectory(bag, required=()).measurements or []
    ks = np.arange(len(measurements))
    np.testing.assert_array_equal([m.com[0] for m in measurements], 1e-4 * (ks % 5000))
    np.testing.assert_allclose([m.t for m in measurements], 0.001 * ks, atol=1e-12)
    assert sum(1 for _ in iter_messages(bag)) == len(ks)
    return len(ks)


@pytest.fixture(scope='module')
def intact_bag(tmp_path_factory) -> tuple[Path, list[tuple[int, int, int]]]:
    """A bag of 3 chunks (compressed) and its chunks as (start byte, end byte, messages)."""
    bag = tmp_path_factory.mktemp('intact') / 'bag'
    with BagWriter(bag) as writer:
        for k in range(6000):
            writer.write_measurement(measurement(k))
    reader = McapReader(bag / 'bag.mcap')      # rosbags' reader of the summary index
    reader.open()
    try:
        chunks = [(c.chunk_start_offset, c.chunk_start_offset + c.chunk_length,
                   sum(c.channel_count.values())) for c in reader.chunks]
    finally:
        reader.close()
    assert len(chunks) >= 3 and sum(n for *_, n in chunks) == 6000
    return bag, chunks


def damaged_copy(intact: Path, target: Path, cut: int) -> Path:
    """``intact`` cut after ``cut`` bytes, without metadata.yaml (as a killed writer leaves it)."""
    target.mkdir()
    data = (intact / 'bag.mcap').read_bytes()[:cut]
    (target / f'{target.name}.mcap').write_bytes(data)
    return target


def test_truncated_at_many_offsets_recovers_every_complete_message(intact_bag, tmp_path):
    bag, chunks = intact_bag
    size = (bag / 'bag.mcap').stat().st_size
    boundaries = [end for _, end, _ in chunks]
    cuts = sorted({9, 200, boundaries[0] - 1, boundaries[0], boundaries[0] + 5, boundaries[1],
                   *np.linspace(300, size - 1, 6).astype(int), size - 8})
    torn_recovered = []
    for i, cut in enumerate(cuts):
        damaged = damaged_copy(bag, tmp_path / f'cut_{i}', int(cut))
        report = repair_bag(damaged)
        whole_chunks = [n for _, end, n in chunks if end <= cut]
        torn = next((n for start, end, n in chunks if start < cut < end), 0)
        recovered = assert_prefix(damaged)
        assert sum(whole_chunks) <= recovered <= sum(whole_chunks) + torn, cut
        assert report.messages == ({MEASUREMENT.name: recovered} if recovered else {})
        assert report.from_torn_chunk == recovered - sum(whole_chunks)
        assert 0 <= report.bytes_dropped < cut
        backup = damaged / f'{damaged.name}.mcap{BACKUP_SUFFIX}'
        assert backup.read_bytes() == (bag / 'bag.mcap').read_bytes()[:cut]
        torn_recovered.append(report.from_torn_chunk)
    # A cut deep inside a chunk recovers the messages of its compressed blocks on disk.
    assert max(torn_recovered) > 0


def test_cut_before_any_complete_message_gives_an_empty_but_valid_bag(intact_bag, tmp_path):
    bag, chunks = intact_bag
    damaged = damaged_copy(bag, tmp_path / 'early', 40)
    report = repair_bag(damaged)
    assert report.status == 'repaired' and report.messages == {}
    with pytest.raises(BagError, match='required topic'):
        read_trajectory(damaged)
    assert list(iter_messages(damaged)) == []


def test_intact_bag_is_left_alone_and_garbage_is_refused(intact_bag, tmp_path):
    bag, _ = intact_bag
    copy = tmp_path / 'bag'
    shutil.copytree(bag, copy)
    assert repair_bag(copy).status == 'intact'
    assert sorted(p.name for p in copy.iterdir()) == ['bag.mcap', 'metadata.yaml']
    junk = tmp_path / 'junk'
    junk.mkdir()
    (junk / 'junk.mcap').write_bytes(b'not an mcap file at all')
    with pytest.raises(BagError, match='not an MCAP file'):
        repair_bag(junk)
    assert (junk / 'junk.mcap').read_bytes() == b'not an mcap file at all'


def test_repair_keeps_messages_recorded_with_an_earlier_definition(tmp_path):
    from test_bagio import (FEATURES_BEFORE_ATTITUDE, assert_features_before_attitude,
                            write_features_before_attitude)
    intact = tmp_path / 'bag'
    write_features_before_attitude(intact, 400)
    size = (intact / 'bag.mcap').stat().st_size
    damaged = damaged_copy(intact, tmp_path / 'killed', size - 8)   # the footer's magic gone
    report = repair_bag(damaged)
    assert report.status == 'repaired' and report.undecodable == {}
    assert report.messages == {FEATURES.name: 400}
    assert_features_before_attitude(read_trajectory(damaged, required=()).features, 400)
    # The repaired bag stores the definition the messages were recorded with.
    with Reader(damaged) as reader:
        [connection] = reader.connections
    assert connection.msgdef.data.startswith(FEATURES_BEFORE_ATTITUDE)


_WRITER = r'''
import sys
sys.path.insert(0, sys.argv[2])
from test_bag_repair import measurement
from fall_predictor.data.bag_writer import BagWriter
with BagWriter(sys.argv[1]) as writer:
    storage = writer._writer.storage
    k, written = 0, 0
    while True:
        writer.write_measurement(measurement(k))
        k += 1
        if storage.bio.tell() != written:       # a chunk went to the file: say how many are safe
            storage.bio.flush()
            written = storage.bio.tell()
            print(k, flush=True)
'''


def test_sigkilled_writer_leaves_a_bag_that_repair_bag_recovers(tmp_path, capsys):
    """A BagWriter process killed mid-write; the CLI repairs the recording it left."""
    run = tmp_path / 'run_000'
    run.mkdir()
    child = subprocess.Popen([sys.executable, '-c', _WRITER, str(run / 'part_000'),
                              str(Path(__file__).parent)], stdout=subprocess.PIPE, text=True)
    try:
        safe = [int(child.stdout.readline()) for _ in range(2)]   # two chunks on disk
        time.sleep(0.2)                                          # mid-way through the third
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait()
    assert child.returncode == -signal.SIGKILL
    assert not (run / 'part_000' / 'metadata.yaml').exists()
    with pytest.warns(UserWarning, match='unfinished part'), pytest.raises(BagError):
        bag_parts(run)
    assert main(['repair-bag', str(run), '--json']) == 0
    summary = json.loads(capsys.readouterr().out)
    recovered = assert_prefix(run)
    assert recovered >= safe[-1]
    assert summary['repaired'] == 1 and summary['messages_recovered'] == {MEASUREMENT.name: recovered}
    assert bag_parts(run) == [run / 'part_000']
    # Running it again finds nothing to do.
    assert main(['repair-bag', str(run), '--json']) == 0
    assert json.loads(capsys.readouterr().out)['repaired'] == 0
