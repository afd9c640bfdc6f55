#!/usr/bin/env python3
"""The per-cause tables of the results page from the evaluations that make them, and whether the
page holds them.

    python scripts/rebuild/cause_table.py docs/prediction/causes.yaml [--check docs/results.md]

The spec (YAML) names each table and its rows: a label (the model and the runs) and an
``evaluate --json`` output, or a leave-one-cause-out study
(``benchmarks/bench_leave_one_cause_out.py``: each model trained without a cause, on that cause);
a table whose entries all name their ``runs`` is a budget table: a model's FPR, misses and lead on
each sampler. Each table is printed in the page's form: one row per cause with
:func:`~fall_predictor.learning.deployment.cause_row` (falls caught, FPR with its Wilson interval,
alarms before the onset, median lead with its bootstrap interval, onset to fall, lead / onset to
fall), the ambiguous push band on its own row, and the hours of undisturbed walking of an
evaluation of long walks in words (:func:`~fall_predictor.learning.deployment.walking_line`).
With ``--check PAGE`` it exits 1 naming every row the page does not hold
(``test/test_readme.py`` runs the check).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from fall_predictor.learning.deployment import cause_row, walking_line  # noqa: E402

HEADER = ('| model, runs | cause | falls caught | FPR [Wilson 95 %] (false alarms / survived) | '
          'alarms before onset | median lead [s] [95 %] | onset to fall [s] (median) | lead / '
          'onset to fall (median) |')
RULE = '|---|---|---|---|---|---|---|---|'


def rows_of(label: str, evaluation: dict[str, Any]) -> list[str]:
    """The table rows (and a walking line) of one evaluation."""
    figures = evaluation['deployment']
    rows = [cause_row(f'{label} | {cause}', f) for cause, f in figures['by_cause'].items()]
    band = figures['ambiguous_push_band']
    if band is not None and len(figures['by_cause']) > 1:
        rows.append(cause_row(f"{label} | push, ambiguous {band['low_ns']:.0f}–"
                              f"{band['high_ns']:.0f} N s", band))
    walking = walking_line(figures['walking'])
    if walking:
        rows.append(f'- {label}: {walking}')
    return rows


def loco_rows(label: str, study: dict[str, Any]) -> list[str]:
    """The rows of a leave-one-cause-out study (benchmarks/bench_leave_one_cause_out.py): each
    model trained without a cause on that cause; the models trained on every cause and on the
    pushes alone on each cause."""
    rows = []
    for name, variant in study['variants'].items():
        held_out = variant['held_out']
        left_out = name.removeprefix('without ') if name.startswith('without ') else None
        causes = [left_out] if left_out else [c for c in held_out if c != 'all_runs']
        trained = f"{label}, {name} ({variant['n_train']} runs)"
        rows += [cause_row(f'{trained} | {cause}', held_out[cause]) for cause in causes]
    return rows


BUDGET_HEADER = ('| model, its budget | runs held out | FPR [Wilson 95 %] | falls missed | lead [s] '
                 '(mean) |')
BUDGET_RULE = '|---|---|---|---|---|'


def budget_row(label: str, runs: str, e: dict[str, Any]) -> str:
    """One row of a budget table: a model's FPR held out on one sampler (``evaluate --json``)."""
    low, high = e['fpr_ci95']
    return (f"| {label} | {runs} | {e['n_false_positives']}/{e['n_balanced']} = {e['fpr']:.3f} "
            f"[{low:.3f}, {high:.3f}] | {e['n_missed']}/{e['n_fallen']} | {e['tau_lead_s']:.2f} |")


def tables(spec_path: Path) -> dict[str, list[str]]:
    """Each table of the spec: its lines (header, rule, rows; walking lines after)."""
    spec = yaml.safe_load(spec_path.read_text())
    out = {}
    for name, entries in spec['tables'].items():
        rows: list[str] = []
        if all('runs' in entry for entry in entries):           # a budget table
            out[name] = [BUDGET_HEADER, BUDGET_RULE] + [
                budget_row(e['label'], e['runs'], json.loads((ROOT / e['evaluation']).read_text()))
                for e in entries]
            continue
        for entry in entries:
            if 'leave_one_cause_out' in entry:
                rows += loco_rows(entry['label'],
                                  json.loads((ROOT / entry['leave_one_cause_out']).read_text()))
                continue
            rows += rows_of(entry['label'], json.loads((ROOT / entry['evaluation']).read_text()))
        table = [r for r in rows if r.startswith('|')]
        words = [r for r in rows if not r.startswith('|')]
        out[name] = ([HEADER, RULE] + table if table else []) + ([''] if table and words else []) + words
    return out


def missing(spec_path: Path, page: Path) -> list[str]:
    """The rows of the spec's tables the page does not hold (each as a whole line)."""
    held = set(page.read_text(encoding='utf-8').splitlines())
    return [line for lines in tables(spec_path).values() for line in lines
            if line and line not in held]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('spec', type=Path)
    parser.add_argument('--check', type=Path, default=None, metavar='PAGE')
    args = parser.parse_args(argv)
    if args.check is not None:
        absent = missing(args.spec, args.check)
        for line in absent:
            print(f'not in {args.check}: {line}')
        return 1 if absent else 0
    for name, lines in tables(args.spec).items():
        print(f'<!-- {name} -->')
        print('\n'.join(lines) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
