#!/usr/bin/env python3
"""A held-out table of the results page from the JSON that makes it, and how a rebuilt one
differs from the committed one.

    python scripts/rebuild/heldout_table.py OUT/heldout [--compare docs/prediction/g1_c_bal/heldout]

``OUT/heldout`` holds ``fall-predictor evaluate --json`` outputs (one per model, ``<model>.json``)
and optionally ``baselines.json`` (``benchmarks/bench_heldout_baselines.py``). Prints the models'
table (FPR with its Wilson interval, lead with its bootstrap interval, misses, lead / oracle,
alarms before the push) and the baselines' (per FPR budget), in the page's form. With
``--compare DIR`` it also prints, per model and baseline, the committed figure beside the rebuilt
one and whether they agree (the same false alarms and misses, lead within 0.005 s), and exits 1
when one does not.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def _load(path: Path) -> dict:
    return json.loads(path.read_text())


def fpr_cell(e: dict) -> str:
    lo, hi = e['fpr_ci95']
    return f'{e["n_false_positives"]}/{e["n_balanced"]} = {e["fpr"]:.3f} [{lo:.3f}, {hi:.3f}]'


def lead_cell(e: dict) -> str:
    if e.get('tau_lead_s') is None:
        return '—'
    lo, hi = e['tau_lead_ci95']
    return f'{e["tau_lead_s"]:.2f} [{lo:.2f}, {hi:.2f}]'


def model_rows(directory: Path) -> dict[str, dict]:
    return {p.stem: _load(p) for p in sorted(directory.glob('*.json'))
            if p.name != 'baselines.json' and not p.name.startswith('train_')}


def baseline_rows(directory: Path) -> dict[tuple[str, float], dict]:
    path = directory / 'baselines.json'
    if not path.exists():
        return {}
    return {(b['baseline'], b['fpr_budget']): b['test'] for b in _load(path)['baselines']}


def table(directory: Path) -> str:
    lines = ['| model (held out) | FPR [95 %] | lead [s] [95 %] | missed | lead / oracle | alarms before the push |',
             '|---|---|---|---|---|---|']
    for name, e in model_rows(directory).items():
        lines.append(f'| `{name}.json` | {fpr_cell(e)} | {lead_cell(e)} | {e["n_missed"]} / {e["n_fallen"]} '
                     f'| {e["lead_fraction"]:.2f} | {e.get("n_pre_push_alarms", 0)} |')
    baselines = baseline_rows(directory)
    if baselines:
        budgets = sorted({budget for _, budget in baselines}, reverse=True)
        lines += ['', '| baseline, budget | ' + ' | '.join(f'FPR ≤ {b:g}' for b in budgets) + ' |',
                  '|---|' + '---|' * len(budgets)]
        for name in sorted({n for n, _ in baselines}):
            cells = [f'{fpr_cell(baselines[name, b])} at {lead_cell(baselines[name, b])}, '
                     f'{baselines[name, b]["n_missed"]} missed' for b in budgets]
            lines.append(f'| {name} | ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)


def agree(a: dict, b: dict) -> bool:
    same_counts = (a['n_false_positives'], a['n_balanced'], a['n_missed'], a['n_fallen']) == \
        (b['n_false_positives'], b['n_balanced'], b['n_missed'], b['n_fallen'])
    lead_a, lead_b = a.get('tau_lead_s'), b.get('tau_lead_s')
    same_lead = (lead_a is None and lead_b is None) or (
        lead_a is not None and lead_b is not None and abs(lead_a - lead_b) <= 0.005)
    return same_counts and same_lead


def compare(rebuilt: Path, committed: Path) -> bool:
    """Print each figure beside the committed one; whether all agree."""
    ok = True
    old_models = model_rows(committed)
    pairs = [(f'`{n}.json`', e, old_models.get(n)) for n, e in model_rows(rebuilt).items()]
    old_baselines = baseline_rows(committed)
    pairs += [(f'{n} ≤ {b:g}', e, old_baselines.get((n, b))) for (n, b), e in baseline_rows(rebuilt).items()]
    print('\n| figure | committed | rebuilt | agree |\n|---|---|---|---|')
    for name, new, old in pairs:
        same = old is not None and agree(new, old)
        ok &= same
        before = 'none' if old is None else f'{fpr_cell(old)} at {lead_cell(old)}'
        print(f'| {name} | {before} | {fpr_cell(new)} at {lead_cell(new)} | {"yes" if same else "**no**"} |')
    return ok


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('heldout', type=Path, help='directory of evaluate outputs (and baselines.json)')
    parser.add_argument('--compare', type=Path, default=None, help='the committed directory')
    args = parser.parse_args(argv)
    print(table(args.heldout))
    if args.compare is not None and not compare(args.heldout, args.compare):
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
