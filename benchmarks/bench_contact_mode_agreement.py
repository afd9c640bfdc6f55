"""Where the estimated contact modes disagree with the simulator's (method §7, §10).

``estimation-error`` gives one number, the fraction of samples whose contact mode from the
estimated state equals the mode of the simulator's true state. This benchmark says where the
rest goes, over the first ``--trajectories`` bags of a dataset made with ``generate
--sensor-noise``:

- by phase: walking before the push, the 0.5 s after it, later, and the last 0.5 s before the
  robot counts as fallen; survived and fallen runs apart;
- by cause: the *support* differs (which feet touch: touchdown and lift-off timing, a lightly
  loaded foot), or the support agrees and the CoP's class (inside, an edge) differs;
- the sole's model: the agreement with the truth's CoP and feet when the truth's contact points
  are replaced by the profile's sole rectangle at the true sole pose (the estimator's geometry).
  What this adds to the agreement is what the rectangle's difference from the real contact
  hull costs; the rest is estimation;
- the most frequent (true, estimated) mode pairs.

``--estimator KEY=VALUE`` (repeatable) runs the estimator with those settings of
:class:`~fall_predictor.monitor.estimator.EstimatorConfig` instead of its defaults (e.g.
``contact_force_n=20``), to see what a setting does to the agreement.

    .venv/bin/python benchmarks/bench_contact_mode_agreement.py --data data/g1_test400 \\
        --trajectories 40 --out docs/estimation/contact_mode_agreement_g1.json
"""
from __future__ import annotations

import argparse
import json
import math
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np
from joblib import Parallel, delayed

from fall_predictor.data.dataset import dataset_robot, read_index
from fall_predictor.data.estimation import (POST_PUSH_WINDOW_S, contact_mode_or_unclassified as mode,
                                           estimate_bag)
from fall_predictor.monitor.estimator import EstimatorConfig
from fall_predictor.monitor.records import CONTACT_MODE_NAMES, SoleGeometry
from fall_predictor.profiles.profile import load_profile

#: The window before the robot counts as fallen that is its own phase [s].
BEFORE_FALLEN_S = 0.5


def on_rectangle(contacts: np.ndarray, sole_pose, sole: SoleGeometry) -> np.ndarray:
    """A touching sole's contact points replaced by its modelled rectangle's corners at the
    sole's pose (x, y, yaw), its normal force split evenly; a sole in the air stays so."""
    if len(contacts) == 0:
        return contacts
    x, y, yaw = (float(v) for v in sole_pose)
    c, s = math.cos(yaw), math.sin(yaw)
    force = float(contacts[:, 2].sum()) / 4
    return np.array([(x + c * dx - s * dy, y + s * dx + c * dy, force)
                     for dx, dy, _ in sole.corners()])


def phase(t: float, row) -> str:
    if row.fallen and t >= row.t_fallen - BEFORE_FALLEN_S:
        return 'last_0.5_s_before_fallen'
    if t < row.t_push:
        return 'before_push'
    return 'post_push_0.5_s' if t <= row.t_push + POST_PUSH_WINDOW_S else 'later'


def one_bag(data: Path, row, robot: str, config: EstimatorConfig) -> dict:
    soles = load_profile(robot).sensor_layout().soles
    b = estimate_bag(data / row.bag, config, robot=robot)
    phases: Counter = Counter()
    counts = Counter()
    pairs: Counter = Counter()
    for t, est, truth in zip(b.t, b.estimated, b.truth):
        if est is None:
            continue
        m_est, m_true = mode(est), mode(truth)
        modelled = replace(truth,
                           left_contacts=on_rectangle(truth.left_contacts, truth.left_foot, soles['l']),
                           right_contacts=on_rectangle(truth.right_contacts, truth.right_foot, soles['r']))
        agree = m_est == m_true
        key = f"{phase(t, row)}/{'fell' if row.fallen else 'survived'}"
        phases[(key, 'n')] += 1
        phases[(key, 'agree')] += agree
        counts['n'] += 1
        counts['agree'] += agree
        counts['agree_with_modelled_sole'] += m_est == mode(modelled)
        support_est = (len(est.left_contacts) > 0, len(est.right_contacts) > 0)
        support_true = (len(truth.left_contacts) > 0, len(truth.right_contacts) > 0)
        if support_est != support_true:
            counts['support_differs'] += 1
            counts['truth_both_estimate_one'] += support_true == (True, True) and any(support_est)
            counts['estimate_both_truth_one'] += support_est == (True, True) and any(support_true)
        elif not agree:
            counts['same_support_class_differs'] += 1
        if not agree:
            pairs[(m_true, m_est)] += 1
    return {'phases': phases, 'counts': counts, 'pairs': pairs}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--data', type=Path, required=True, help='dataset made with --sensor-noise')
    parser.add_argument('--trajectories', type=int, default=40, help='the first N bags')
    parser.add_argument('--estimator', action='append', default=[], metavar='KEY=VALUE',
                        help='an EstimatorConfig setting (a number), repeatable')
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    settings = {}
    for item in args.estimator:
        key, _, value = item.partition('=')
        if key not in EstimatorConfig.__dataclass_fields__:
            parser.error(f'--estimator {item}: EstimatorConfig has no {key!r}')
        settings[key] = float(value)
    config = replace(EstimatorConfig(), **settings)
    robot = dataset_robot(args.data)
    rows = read_index(args.data)[:args.trajectories]
    results = Parallel(n_jobs=args.jobs)(delayed(one_bag)(args.data, row, robot, config) for row in rows)
    phases, counts, pairs = Counter(), Counter(), Counter()
    for r in results:
        phases.update(r['phases'])
        counts.update(r['counts'])
        pairs.update(r['pairs'])
    n = counts['n']
    n_disagree = n - counts['agree']

    def name(k: int) -> str:
        return CONTACT_MODE_NAMES[k] if k >= 0 else 'unclassifiable'
    out = {'data': str(args.data), 'robot': robot, 'trajectories': len(rows), 'samples': n,
           'estimator_settings': settings,
           'agreement': counts['agree'] / n,
           'agreement_with_truth_on_modelled_sole': counts['agree_with_modelled_sole'] / n,
           'of_all_samples': {k: counts[k] / n for k in ('support_differs', 'truth_both_estimate_one',
                                                         'estimate_both_truth_one',
                                                         'same_support_class_differs')},
           'by_phase': {key: {'samples': phases[(key, 'n')], 'agreement': phases[(key, 'agree')] / phases[(key, 'n')]}
                        for key in sorted({k for k, _ in phases})},
           'top_disagreements': [{'true': name(t), 'estimated': name(e), 'share_of_disagreements': c / n_disagree}
                                 for (t, e), c in pairs.most_common(12)]}
    text = json.dumps(out, indent=1)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + '\n')
    print(text)
    return out


if __name__ == '__main__':
    main()
