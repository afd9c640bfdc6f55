"""What generating a dataset cost, and where: per trajectory, and summed in ``dataset.json``.

Each simulated trajectory comes back with a cost record (:func:`trajectory_cost`): the CPU
seconds of the thread that simulated and recorded it, its wall time, the simulated seconds, and
the machine and worker that ran it. The record is kept as ``costs/<trajectory id>.json`` beside
the index row, so a run that was interrupted and resumed still accounts for every trajectory.
At the end of every run :func:`record_generation_cost` sums the records into the ``generation``
entry of ``dataset.json`` (total CPU seconds, CPU per simulated second, per machine: cores,
trajectories, CPU seconds and workers) and appends the run (start, wall time, jobs, scheduler).
The entry is bookkeeping, not a setting: a resumed run ignores it when it checks that the
settings match.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from fall_predictor.data.parallel import machine, worker_name
from fall_predictor.monitor.fileio import atomic_write_text

#: Directory of the per-trajectory cost records, and the manifest entry that sums them.
COSTS_DIR = 'costs'
GENERATION_COST_KEY = 'generation'


def trajectory_cost(cpu_s: float, wall_s: float, simulated_s: float) -> dict[str, Any]:
    """The cost record of one trajectory simulated by the calling thread."""
    host = machine()
    return {'cpu_s': round(cpu_s, 4), 'wall_s': round(wall_s, 4), 'simulated_s': round(simulated_s, 4),
            'host': host['host'], 'cores': host['cores'], 'worker': worker_name()}


def summarise_costs(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Totals over cost records, and per machine (host): cores, trajectories, CPU s, workers."""
    machines: dict[str, dict[str, Any]] = {}
    for r in records:
        m = machines.setdefault(r['host'], {'cores': r['cores'], 'trajectories': 0, 'cpu_s': 0.0,
                                            'workers': set()})
        m['trajectories'] += 1
        m['cpu_s'] += r['cpu_s']
        m['workers'].add(r['worker'])
    cpu_s = sum(r['cpu_s'] for r in records)
    simulated_s = sum(r['simulated_s'] for r in records)
    return {'trajectories': len(records), 'cpu_s': round(cpu_s, 3),
            'simulated_s': round(simulated_s, 3),
            'cpu_per_simulated_s': round(cpu_s / simulated_s, 4) if simulated_s > 0 else None,
            'machines': {host: {**m, 'cpu_s': round(m['cpu_s'], 3), 'workers': sorted(m['workers'])}
                         for host, m in sorted(machines.items())}}


def record_generation_cost(out: Path, run: dict[str, Any]) -> dict[str, Any]:
    """Sum the cost records of dataset ``out`` into its ``dataset.json`` and append ``run``;
    returns the new ``generation`` entry."""
    records = []
    for path in sorted((out / COSTS_DIR).glob('traj_*.json')):
        if not (out / 'index' / path.name).exists():
            continue                       # a run killed before its index row: not committed
        try:
            records.append(json.loads(path.read_text()))
        except (OSError, json.JSONDecodeError):
            continue                       # a lost record only makes the totals incomplete
    manifest_path = out / 'dataset.json'
    manifest = json.loads(manifest_path.read_text())
    previous = manifest.get(GENERATION_COST_KEY, {})
    entry = {**summarise_costs(records), 'runs': list(previous.get('runs', [])) + [run]}
    manifest[GENERATION_COST_KEY] = entry
    atomic_write_text(manifest_path, json.dumps(manifest, indent=1, sort_keys=True))
    return entry
