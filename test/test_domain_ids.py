"""The ROS domain ids of the DDS tests: valid for Fast DDS, distinct within one run (one process,
or the parallel workers of one run).

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


def test_no_two_modules_share_an_offset() -> None:
    """Parallel workers run whole modules at once (scripts/test.sh: ``--dist loadfile``): a shared
    offset would put two of them on one domain, each seeing the other's nodes."""
    pattern = re.compile(r'test_domain_id\((\d+)\)')
    owner: dict[int, str] = {}
    for path in sorted(TEST_DIR.glob('test_*.py')):
        if path.name == Path(__file__).name:      # this module names offsets as examples
            continue
        for offset in {int(m) for m in pattern.findall(path.read_text())}:
            assert owner.setdefault(offset, path.name) == path.name, (offset, owner[offset], path.name)


def test_the_workers_of_one_run_share_the_runs_part(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv('PYTEST_XDIST_TESTRUNUID', '9f86d081884c7d65')
    ids = set()
    for pid in (1234, 5678):                      # two workers of the run
        monkeypatch.setattr(os, 'getpid', lambda pid=pid: pid)
        ids.add(test_domain_id(100))
    assert ids == {1 + (int('9f86d081', 16) % 70 + 100) % MAX_DOMAIN_ID}


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
