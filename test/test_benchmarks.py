"""The benchmarks still run against the package: each imports (its own imports and the package
names it uses at module level resolve), without running. ``bench_soak.py`` had stopped importing
when the typed interface replaced the arrays it published, and nothing noticed for sessions."""
from __future__ import annotations

import importlib
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / 'benchmarks'
SCRIPTS = sorted(p.stem for p in BENCHMARKS.glob('bench_*.py'))


def test_every_benchmark_is_found() -> None:
    assert len(SCRIPTS) >= 20 and 'bench_soak' in SCRIPTS


@pytest.mark.parametrize('name', SCRIPTS)
def test_benchmark_imports(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(BENCHMARKS))         # as when run: python benchmarks/X.py
    module = importlib.import_module(name)
    assert callable(getattr(module, 'main', None)), f'{name} has no main()'
    sys.modules.pop(name, None)
