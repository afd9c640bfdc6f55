"""FPR and tau_lead of a model on estimated state as the sensor noise grows (0x, 1x, 2x, 4x).

The same trajectories (one seed: the same pushes, gaits and physics; sensor noise is applied on
top of the simulated sensor quantities) are generated once per noise scale with
``generate --sensor-noise SCALE``; the model is evaluated on the state the estimator makes from
each (``--state estimated``) and once on the exact state (``--state true``) for reference.
Writes a JSON file and a PNG plot (FPR with its Wilson 95 % interval, tau_lead with its
bootstrap 95 % interval, against the noise scale).

Usage::

    python benchmarks/bench_noise_sweep.py --model models/default_model.json \
        --trajectories 100 --seed 1 --work data/noise --jobs 2 \
        --out docs/estimation/noise_sweep.json --plot docs/estimation/noise_sweep.png

Generation resumes: rerunning with the same --work reuses finished trajectories.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

SCALES = (0.0, 1.0, 2.0, 4.0)


def _figures(result) -> dict:
    return {'n_trajectories': result.n_trajectories, 'n_fallen': result.n_fallen,
            'fpr': result.fpr, 'fpr_ci95': list(result.fpr_ci95),
            'n_false_positives': result.n_false_positives, 'n_balanced': result.n_balanced,
            'tau_lead_s': result.tau_lead_s, 'tau_lead_ci95': list(result.tau_lead_ci95),
            'n_missed': result.n_missed, 'misses_lists_only': result.n_missed_lists_only,
            'tau_lead_lists_only_s': result.tau_lead_lists_only_s}


def _plot(document: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    rows = document['estimated']
    x = [r['noise_scale'] for r in rows]
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
    for ax, key, ci, label in ((axes[0], 'fpr', 'fpr_ci95', 'FPR (Wilson 95 %)'),
                               (axes[1], 'tau_lead_s', 'tau_lead_ci95', 'tau_lead [s] (bootstrap 95 %)')):
        y = [r[key] for r in rows]
        lo = [r[key] - r[ci][0] for r in rows]
        hi = [r[ci][1] - r[key] for r in rows]
        ax.errorbar(x, y, yerr=[lo, hi], fmt='o-', capsize=3, label='estimated state')
        true = document['true_state']
        ax.axhline(true[key], color='k', ls='--', lw=1, label='true state')
        ax.axhspan(true[ci][0], true[ci][1], color='k', alpha=0.08)
        ax.set_xlabel('sensor noise (x default)')
        ax.set_ylabel(label)
        ax.set_xticks(list(SCALES))
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{document['model']} on {rows[0]['n_trajectories']} trajectories (seed {document['seed']}), "
                 f"tau_his {document['tau_his_s']} s", fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def main() -> None:
    from fall_predictor.data.generation import GenerationConfig, generate_dataset
    from fall_predictor.learning.evaluation import evaluate_model
    from fall_predictor.monitor.model_file import load_model

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--model', type=Path, default=Path('models/default_model.json'))
    parser.add_argument('--trajectories', type=int, default=100)
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--work', type=Path, required=True, help='where the datasets are generated')
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', type=Path, default=Path('docs/estimation/noise_sweep.json'))
    parser.add_argument('--plot', type=Path, default=Path('docs/estimation/noise_sweep.png'))
    args = parser.parse_args()
    lists, metadata = load_model(args.model)
    tau_his = metadata.recommended_tau_his_s
    guard = metadata.feature_settings.guard_com_height_m      # the model's, as `evaluate` uses it
    started = time.perf_counter()
    rows, true_state = [], None
    for scale in SCALES:
        data = args.work / f'noise_{scale:g}x'
        generate_dataset(data, args.trajectories, args.seed, jobs=args.jobs,
                         config=GenerationConfig(seed=args.seed, sensor_noise_scale=scale))
        evaluation = evaluate_model(data, lists, tau_his, jobs=args.jobs, progress=True, state='estimated',
                                    guard_com_height_m=guard)
        rows.append({'noise_scale': scale, **_figures(evaluation.result)})
        print(json.dumps(rows[-1]), flush=True)
        if true_state is None:
            true_state = _figures(evaluate_model(data, lists, tau_his, jobs=args.jobs, state='true',
                                                 guard_com_height_m=guard).result)
    document = {'command': 'python benchmarks/bench_noise_sweep.py ' + ' '.join(
                    f'--{k.replace("_", "-")} {v}' for k, v in vars(args).items()),
                'model': str(args.model), 'model_state': metadata.state, 'tau_his_s': tau_his,
                'seed': args.seed, 'estimated': rows, 'true_state': true_state,
                'wall_s': round(time.perf_counter() - started, 1)}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(document, indent=1) + '\n')
    _plot(document, args.plot)
    print(json.dumps(document))


if __name__ == '__main__':
    main()
