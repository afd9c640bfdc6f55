"""The ROS domain ids of the DDS tests: valid for Fast DDS and distinct within one process.

An id above 232 makes Fast DDS end the whole test process with exit(1) and no Python error
(the suite then stops without a summary), so every offset the tests use is checked for every
value the pid can contribute.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from test_nodes_support import MAX_DOMAIN_ID, test_domain_id

TEST_DIR = Path(__file__).parent


def _offsets_used_by_the_suite() -> set[int]:
    pattern = re.compile(r'test_domain_id\((\d+)\)')
    return {int(m) for path in TEST_DIR.glob('test_*.py') for m in pattern.findall(path.read_text())}


def test_every_offset_gives_a_valid_distinct_id_for_every_pid(monkeypatch: pytest.MonkeyPatch) -> None:
    offsets = _offsets_used_by_the_suite()
    assert {0, 100, 165} <= offsets          # the scan finds the modules' offsets
    for pid in range(70):
        monkeypatch.setattr(os, 'getpid', lambda pid=pid: pid)
        ids = [test_domain_id(offset) for offset in sorted(offsets)]
        assert all(1 <= i <= MAX_DOMAIN_ID for i in ids), (pid, ids)
        assert len(set(ids)) == len(ids), (pid, ids)


def test_an_offset_outside_the_range_is_refused() -> None:
    with pytest.raises(ValueError):
        test_domain_id(MAX_DOMAIN_ID)
