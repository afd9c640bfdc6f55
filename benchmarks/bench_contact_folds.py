"""How often the double-stance contact-mode folds happen on a dataset.

For every 1 kHz measurement of the first ``--limit`` trajectories of ``--data`` (every one by
default) the support polygon is built as :mod:`fall_predictor.monitor.contact_modes` does and,
for double-stance samples whose CoP lies only on lateral edges (outward normal nearer +-y than
+-x), it counts how the fold resolves: to LR-FRONT, to LR-BACK (diagonal edges, by the sign of
the normal's sagittal component) or to LR-INSIDE (a purely lateral edge). Before these folds, all of
them were LR-INSIDE. Prints one JSON object; ``--out`` also writes it.

Usage: ``python benchmarks/bench_contact_folds.py --data DATA [--limit N] [--out F.json]``
"""
from __future__ import annotations

import argparse
import json
import math
from collections import Counter
from pathlib import Path

from tqdm import tqdm

from fall_predictor.data.bagio import read_trajectory
from fall_predictor.data.dataset import read_index
from fall_predictor.monitor.contact_modes import (_contact_rows, _cop_xy, _polygon_normals,
                                                  _sides_from_normals, classify_contact_mode,
                                                  convex_hull, lr_lateral_edge_fold)
from fall_predictor.monitor.records import CONTACT_MODE_NAMES


def fold_of(m, edge_tolerance_m: float = 0.01):
    """'FRONT', 'BACK', 'INSIDE' for a double-stance sample on lateral edges only, else None."""
    left = _contact_rows(m.left_contacts, 'left_contacts')
    right = _contact_rows(m.right_contacts, 'right_contacts')
    if not (left and right):
        return None
    rows = left + right
    hull = convex_hull([(r[0], r[1]) for r in rows])
    if len(hull) < 3:
        return None
    x, y = _cop_xy(m.cop, rows)
    c, s = math.cos(float(m.heading)), math.sin(float(m.heading))
    normals = _polygon_normals(x, y, hull, edge_tolerance_m)
    x_side, y_side = _sides_from_normals(normals, c, s)
    if x_side is not None or y_side is None:
        return None
    return lr_lateral_edge_fold(normals, c, s) or 'INSIDE'


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--data', required=True)
    parser.add_argument('--limit', type=int, default=None)
    parser.add_argument('--out', default=None)
    args = parser.parse_args()
    rows = read_index(args.data)[:args.limit]
    folds, modes = Counter(), Counter()
    trajectories_with = Counter()
    for row in tqdm(rows, unit='traj'):
        seen = set()
        for m in read_trajectory(Path(args.data) / row.bag).measurements:
            modes[CONTACT_MODE_NAMES[classify_contact_mode(m)]] += 1
            fold = fold_of(m)
            if fold is not None:
                folds[fold] += 1
                seen.add(fold)
        trajectories_with.update(seen)
    n = sum(modes.values())
    lr = sum(v for k, v in modes.items() if k.startswith('LR-'))
    result = {
        'data': Path(args.data).name, 'trajectories': len(rows), 'samples': n,
        'double_stance_samples': lr,
        'lateral_edge_samples': {k: folds[k] for k in ('FRONT', 'BACK', 'INSIDE')},
        'lateral_edge_fraction_of_double_stance': {
            k: round(folds[k] / lr, 5) if lr else None for k in ('FRONT', 'BACK', 'INSIDE')},
        'trajectories_with_fold': {k: trajectories_with[k] for k in ('FRONT', 'BACK', 'INSIDE')},
        'mode_samples_after_fold': dict(sorted(modes.items())),
        'command': 'python benchmarks/bench_contact_folds.py --data DATA'
                   + (f' --limit {args.limit}' if args.limit else ''),
    }
    text = json.dumps(result, indent=1)
    print(text)
    if args.out:
        Path(args.out).write_text(text + '\n')


if __name__ == '__main__':
    main()
