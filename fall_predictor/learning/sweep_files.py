"""The sweep's files: :func:`run_sweep` computes the sweep
(:func:`fall_predictor.learning.sweep.compute_sweep`) and :func:`write_sweep_files` writes what it
computed: the PNG figures (:mod:`fall_predictor.learning.plots`,
:mod:`fall_predictor.learning.plots_intervals`), ``sweep.json`` and ``table.md``
(:mod:`fall_predictor.learning.report`). The computing and the writing modules import only the
results (:mod:`fall_predictor.learning.sweep_results`), never each other.
"""
from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path
from typing import Optional

from fall_predictor.learning.nested import nested_report_json
from fall_predictor.learning.plots import plot_sweep
from fall_predictor.learning.plots_intervals import plot_pareto_intervals
from fall_predictor.learning.report import sweep_json, sweep_table
from fall_predictor.learning.sweep import compute_sweep
from fall_predictor.learning.sweep_results import SweepConfig, SweepResult
from fall_predictor.learning.training import PathLike
from fall_predictor.monitor.fileio import atomic_write_text


def write_sweep_files(result: SweepResult, out_dir: PathLike) -> SweepResult:
    """Write ``result``'s figures, ``sweep.json`` and ``table.md`` to ``out_dir`` (created if
    missing, each file atomically); returns ``result`` with the written ``files`` and the
    figures' wall time added to its timing (``plots_s``, and to ``total_s``), as written in
    ``sweep.json``."""
    out_dir = Path(out_dir)
    start = time.perf_counter()
    out_dir.mkdir(parents=True, exist_ok=True)
    figures = plot_sweep(out_dir, result.points, result.pareto, result.selected,
                         result.learning_curve, result.baselines, result.config)
    grid_fits = result.grid_fits
    if grid_fits:
        figures = list(figures) + [plot_pareto_intervals(
            out_dir / 'pareto_intervals.png', grid_fits, result.points,
            nested_report_json(grid_fits, {}), result.baselines_nested)]
    plots_s = time.perf_counter() - start
    timing = dataclasses.replace(result.timing, plots_s=plots_s,
                                 total_s=result.timing.total_s + plots_s)
    result = dataclasses.replace(
        result, timing=timing,
        files=tuple(str(p) for p in figures) + (str(out_dir / 'sweep.json'), str(out_dir / 'table.md')))
    atomic_write_text(out_dir / 'sweep.json', json.dumps(sweep_json(result), indent=1) + '\n')
    atomic_write_text(out_dir / 'table.md', sweep_table(result))
    return result


def run_sweep(data_dir: PathLike, out_dir: PathLike, config: SweepConfig = SweepConfig(),
              jobs: int = 1, skip_unreadable: bool = False, progress: bool = False,
              command: Optional[str] = None, scheduler: Optional[str] = None) -> SweepResult:
    """:func:`~fall_predictor.learning.sweep.compute_sweep` on the dataset ``data_dir``, then
    :func:`write_sweep_files` to ``out_dir``; returns the result with the files it wrote."""
    result = compute_sweep(data_dir, config, jobs=jobs, skip_unreadable=skip_unreadable,
                           progress=progress, command=command, scheduler=scheduler)
    return write_sweep_files(result, out_dir)
