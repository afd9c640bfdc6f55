#!/usr/bin/env python3
"""Split a dataset into two by trajectory index: the first N runs and the rest, each a dataset
directory every offline tool reads (its manifest, its index rows, its bags linked, its feature
cache linked so nothing is derived again).

    python scripts/rebuild/split_dataset.py DATA/g1_test1000_5050 --first 500 DATA/part_a DATA/part_b

Runs are drawn from (seed, index) alone, so the halves are independent samples of the same push
distribution: one half can train a model that the other half then tests, held out. The manifests
record the split (``split_of``). Bags and cache entries are linked, not copied (hard links for the
cache where the file system allows them, so that a rebuilt entry never changes the source's).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from fall_predictor.data.dataset import read_index, read_manifest, write_index_csv  # noqa: E402


def _link_or_copy(source: Path, target: Path) -> None:
    try:
        os.link(source, target)
    except OSError:
        shutil.copy2(source, target)


def write_part(source: Path, out: Path, rows: list, first: int, count: int) -> None:
    """Dataset ``out`` holding ``rows`` of ``source`` (indices ``first`` .. ``first + count - 1``)."""
    if out.exists():
        raise SystemExit(f'{out} exists: give a new directory')
    (out / 'index').mkdir(parents=True)
    (out / 'bags').mkdir()
    (out / 'cache').mkdir()
    manifest = read_manifest(source)
    manifest['split_of'] = {'data': str(source), 'first_index': first, 'trajectories': count}
    (out / 'dataset.json').write_text(json.dumps(manifest, indent=1))
    for row in rows:
        tid = row.trajectory_id
        shutil.copy2(source / 'index' / f'{tid}.json', out / 'index' / f'{tid}.json')
        (out / row.bag).symlink_to((source / row.bag).resolve(), target_is_directory=True)
        for entry in (source / 'cache').glob(f'*{tid}*.npz'):
            _link_or_copy(entry, out / 'cache' / entry.name)
    write_index_csv(out, rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('data', type=Path, help='the dataset to split')
    parser.add_argument('--first', type=int, required=True, help='runs in the first part')
    parser.add_argument('out_a', type=Path, help='the first part (indices 0 .. N-1)')
    parser.add_argument('out_b', type=Path, help='the second part (the rest)')
    args = parser.parse_args(argv)
    rows = read_index(args.data)
    if not 0 < args.first < len(rows):
        parser.error(f'--first must be within 1 .. {len(rows) - 1} ({len(rows)} runs)')
    write_part(args.data, args.out_a, rows[:args.first], 0, args.first)
    write_part(args.data, args.out_b, rows[args.first:], args.first, len(rows) - args.first)
    print(json.dumps({'a': str(args.out_a), 'a_runs': args.first, 'b': str(args.out_b),
                      'b_runs': len(rows) - args.first}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
