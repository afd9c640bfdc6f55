#!/usr/bin/env python3
"""The same N trajectories with ``generate --jobs 2`` (loky) and on a local Dask cluster of two
single-threaded workers (a ``dask scheduler`` and two ``dask worker`` processes started here),
one after the other. Writes wall and CPU seconds, the overhead ratio, each dataset's
``generation`` cost record, and whether the two datasets' index rows are identical.

    .venv/bin/python benchmarks/bench_scale_out.py --trajectories 200 --work-dir data/scale \
        --out docs/scale_out/scale_out_200.json
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path


def children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def generate(folder: Path, n: int, seed: int, extra: list[str]) -> None:
    subprocess.run([sys.executable, '-m', 'fall_predictor.cli', 'generate', '--trajectories', str(n),
                    '--seed', str(seed), '--out', str(folder), '--json', *extra],
                   check=True, stdout=subprocess.DEVNULL)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--trajectories', type=int, default=200)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--work-dir', type=Path, required=True, help='where the two datasets go')
    parser.add_argument('--port', type=int, default=8799)
    parser.add_argument('--out', type=Path)
    args = parser.parse_args()
    result: dict = {'trajectories': args.trajectories, 'seed': args.seed, 'cpus': os.cpu_count()}
    for name in ('jobs2', 'dask2'):
        folder = args.work_dir / f'ds_{name}'
        shutil.rmtree(folder, ignore_errors=True)
        load0, cpu0, t0 = os.getloadavg()[0], children_cpu_s(), time.perf_counter()
        startup = 0.0
        if name == 'jobs2':
            generate(folder, args.trajectories, args.seed, ['--jobs', '2'])
            wall = time.perf_counter() - t0
        else:
            address = f'tcp://127.0.0.1:{args.port}'
            quiet = {'stdout': subprocess.DEVNULL, 'stderr': subprocess.DEVNULL}
            processes = [subprocess.Popen([sys.executable, '-m', 'distributed.cli.dask_scheduler', '--port',
                                           str(args.port), '--dashboard-address', ':0', '--no-show'], **quiet)]
            processes += [subprocess.Popen([sys.executable, '-m', 'distributed.cli.dask_worker', address,
                                            '--nthreads', '1', '--nworkers', '1', '--no-dashboard'], **quiet)
                          for _ in range(2)]
            try:
                time.sleep(8)
                startup = time.perf_counter() - t0
                t1 = time.perf_counter()
                generate(folder, args.trajectories, args.seed, ['--scheduler', address])
                wall = time.perf_counter() - t1
            finally:
                for process in reversed(processes):
                    process.terminate()
                for process in processes:
                    process.wait(30)
        cost = json.loads((folder / 'dataset.json').read_text())['generation']
        result[name] = {'wall_s': wall, 'process_cpu_s': children_cpu_s() - cpu0, 'cluster_startup_s': startup,
                        'load_average_1min_start': load0, 'load_average_1min_end': os.getloadavg()[0],
                        'generation': cost}
        print(name, result[name], flush=True)
    rows = [sorted((p.name, p.read_text()) for p in (args.work_dir / f'ds_{n}' / 'index').glob('*.json'))
            for n in ('jobs2', 'dask2')]
    result['index_rows_identical'] = rows[0] == rows[1]
    result['dask_over_jobs2_wall'] = result['dask2']['wall_s'] / result['jobs2']['wall_s']
    output = json.dumps(result, indent=1)
    print(output)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(output + '\n')


if __name__ == '__main__':
    main()
