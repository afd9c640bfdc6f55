"""Boosted trees against the decision lists (method §8a), selected by nested CV, then held out.

On the development data (``--data``), k-fold CV by trajectory (the sweep's folds): each fold
trains the decision lists (``tree``) and the boosted trees (``boosting``, ``--param`` for its
hyper-parameters) at the same tau_plus, on the same weighted samples (``--mirror``: with the
left-right mirror images, both). The boosted trees are trained once per fold and their score
thresholded at every ``--thresholds`` value (log-odds); the lists' setting is tau_his, the
boosted trees' is (decision threshold, tau_his). ``--tau-plus`` repeated trains each learner at
each tau_plus, which joins the setting: (tau_plus, decision threshold, tau_his). For each FPR
budget the operating point is chosen as :func:`~fall_predictor.learning.nested.nested_over_grid`
does (on the other folds, reported on each), with Wilson / bootstrap intervals. As ``train``
does (method §11 "A budget that holds"), the budget is checked on the one-sided Wilson upper
bound of the pooled FPR (``--fpr-rule ucb``, ``--fpr-level``; ``point``: on the pooled FPR, as
the results made before this rule were) and the folds are grouped by cause and push impulse
band (``--folds-by cause_band``; ``outcome``: the sweep's stratified folds).

With ``--test``: both learners trained on all the development data, each budget's setting
chosen on all the development folds, evaluated once on the test set; and each final model's
cost per 1 kHz decision (``predict_one``, one sample at a time as the monitor calls it, over
the test set's samples). Writes JSON (``--out``).

With ``--fixed LEARNER:THRESHOLD,TAU_HIS[,TAU_PLUS]`` (repeatable; TAU_PLUS needed with several
``--tau-plus``), a setting fixed in advance, such as a shipped model's own, is reported beside
the nested choices: pooled over the folds (no selection, so no nesting) and, with ``--test``,
held out.

With ``--window``, another learner, ``boosting_window``: the same boosting on the features and
their changes over the last 50, 100 and 200 ms (60 inputs; :class:`ExtraInputsBoosting`),
selected and evaluated alike: what a window of the recent past buys by nested CV. With
``--imu``, ``boosting_imu``: the same on the features and the IMU tilt detector's four signals
(19 inputs; :class:`ImuInputs`): what features from the IMU buy. Offline references: the onboard
monitor computes no such inputs (no cost per decision is given for them). With ``--attitude``,
``boosting_attitude``: the package's own boosted trees on the features and the base's attitude
from the estimated state (method §8c, ``train --attitude``), which the monitor does compute (its
cost per decision is given). With ``--push-time``, ``boosting_push_time``: the same boosting on
the features and the time since the push's onset (:func:`with_time_since_push`), which the
monitor is never told: a privileged reference for what knowing when the push came would buy.
With ``--cusum``, ``boosting_cusum``: the boosted trees' scores under another decision rule, the
evidence accumulated since it last was none (Page's CUSUM, :func:`cusum_evidence`) instead of
the history window; its setting (tau_plus, drift, level) chosen by the same nested CV.

    .venv/bin/python benchmarks/bench_boosted_trees.py --data data/g1_dev1000 \\
        --test data/g1_test1000_5050 --folds 5 --mirror --attitude --tau-plus=-1.0 \\
        --tau-plus=-0.75 --tau-plus=-0.5 --tau-plus=-0.25 --tau-plus=0 \\
        --out docs/prediction/g1_c_bal/nested_tau_plus_grid.json
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from fall_predictor.cli.args import learner_param
from fall_predictor.data.dataset import dataset_guard_com_height_m
from fall_predictor.data.dataset import read_index
from fall_predictor.learning.crossval import grouped_trajectory_folds, stratified_trajectory_folds
from fall_predictor.learning.evaluation import evaluation_result_json
from fall_predictor.learning.metrics import evaluate_atomic
from fall_predictor.learning.mirror import ATTITUDE_MIRROR_SIGNS, MIRROR_ID_SUFFIX
from fall_predictor.learning.nested import nested_over_grid, pool_results
from fall_predictor.learning.run_groups import disturbances, fold_groups
from fall_predictor.learning.training import fit_strided, load_dataset, make_learner, model_inputs
from fall_predictor.monitor.records import ATTITUDE_NAMES, FALLING, N_CONTACT_MODES

# --window: the features and their changes over these lags, as the temporal-window benchmark
# makes them (this directory is on the path when a benchmark runs as a script).
from bench_temporal_window import LAGS_S as WINDOW_LAGS_S, windowed  # noqa: E402

TAU_HIS_S = (0.0, 0.016, 0.03, 0.044, 0.06, 0.08, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4)
# Up to 6: at the FPR-0 budget the G1's and the ASIMO-like robot's boosted trees chose 4.0 once the
# grid went past 3.0, its old edge (docs/prediction/g1_c_bal/nested_attitude.json).
THRESHOLDS = (0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0)
BUDGETS = (0.0, 0.01, 0.06)
# Widened twice: a first grid (levels up to 0.32, drifts -1 to 3) chose its highest level at the
# low false-alarm budgets, a second (levels to 1.28, drifts -1 to 6) its lowest drift at <= 0.01.
#: The CUSUM rule's grids: the drift subtracted from each sample's score [log-odds] and the
#: level the accumulated evidence must pass [log-odds s]; scores clipped to +-SCORE_CLIP_LOG_ODDS
#: (a mode held by a constant list scores +-inf).
CUSUM_DRIFTS = (-4.0, -2.0, -1.0, 0.0, 1.0, 2.0, 4.0)
CUSUM_LEVELS_S = (0.02, 0.04, 0.08, 0.16, 0.32, 0.64, 1.28, 2.56)
SCORE_CLIP_LOG_ODDS = 10.0
KEEP = ('n_balanced', 'n_false_positives', 'fpr', 'fpr_ci95', 'n_fallen', 'tau_lead_s',
        'tau_lead_ci95', 'n_missed', 'lead_fraction')


def scores(lists, traj) -> np.ndarray:
    """Per sample the boosted score of its mode (a mode held by a decision list: +-inf)."""
    return lists.score(traj.X, traj.mode)


def fold_results(lists, trajs, kind: str, thresholds, guard_m: float) -> dict:
    """{threshold: {tau_his: EvaluationResult}} (the lists: threshold 0 only)."""
    if kind == 'tree':
        atomic = [lists.predict(t.X, t.mode) == FALLING for t in trajs]
        return {0.0: evaluate_atomic(trajs, atomic, TAU_HIS_S, 0.001, guard_m)}
    if isinstance(lists, ExtraInputsBoosting):
        per_traj = [lists.scores(t) for t in trajs]
    else:
        per_traj = [scores(lists, t) for t in trajs]
    return {thr: evaluate_atomic(trajs, [s > thr for s in per_traj], TAU_HIS_S, 0.001, guard_m)
            for thr in thresholds}


def cusum_evidence(score: np.ndarray, drift: float, dt_s: float = 0.001) -> np.ndarray:
    """Page's CUSUM of ``score - drift`` per sample [log-odds s]: the evidence accumulated since it
    was last at zero, ``E_k = max(0, E_{k-1} + (score_k - drift) dt)`` with ``E_{-1} = 0``, as the
    running sum less its running minimum (at most zero)."""
    total = np.cumsum((np.clip(score, -SCORE_CLIP_LOG_ODDS, SCORE_CLIP_LOG_ODDS) - drift) * dt_s)
    return total - np.minimum(np.minimum.accumulate(total), 0.0)


def cusum_results(lists, trajs, guard_m: float, drifts=CUSUM_DRIFTS,
                  levels_s=CUSUM_LEVELS_S) -> dict:
    """{(drift, level): EvaluationResult} of the CUSUM rule on a boosted model's scores (falling
    from the first sample whose evidence exceeds the level; the CoM guard as always)."""
    per_traj = [scores(lists, t) for t in trajs]
    out = {}
    for drift in drifts:
        evidence = [cusum_evidence(s, drift) for s in per_traj]
        for level in levels_s:
            out[(drift, level)] = evaluate_atomic(trajs, [e > level for e in evidence], (0.0,),
                                                  0.001, guard_m)[0.0]
    return out


class ExtraInputsBoosting:
    """The boosting learner on the 15 features and more inputs (``inputs``: a trajectory -> the
    trajectory with its inputs as ``X``), per contact mode, as ``fit_strided`` trains it (mirror
    images made from the 15 features first). An offline reference: its trees take inputs the
    onboard monitor does not compute; scores from scikit-learn's ``decision_function``, which the
    exported trees equal bit for bit (test_boosting.py)."""

    def __init__(self, params: dict, inputs) -> None:
        self.params = params
        self.inputs = inputs

    def fit(self, trajs, tau_plus_s: float, mirror: bool) -> 'ExtraInputsBoosting':
        from sklearn.ensemble import HistGradientBoostingClassifier

        from fall_predictor.learning.learners import training_set
        from fall_predictor.learning.training import (BALANCED_WEIGHT, DEFAULT_SAMPLE_STRIDE,
                                                      FALLING_WEIGHT, subsample)
        if mirror:
            from fall_predictor.learning.mirror import with_mirror_images
            trajs = with_mirror_images(trajs)
        stride = DEFAULT_SAMPLE_STRIDE
        X, y, w, modes, _ = training_set([subsample(self.inputs(t), stride) for t in trajs],
                                              tau_plus_s, BALANCED_WEIGHT * stride,
                                              FALLING_WEIGHT * stride)
        hp = make_learner('boosting', self.params)      # its validated hyper-parameters
        self.models = {}
        for mode in range(N_CONTACT_MODES):
            falling = y[modes == mode] == FALLING
            if not falling.any():
                continue
            if falling.all():
                self.models[mode] = np.inf              # every sample falling: a constant score
                continue
            # As BoostedTreesLearner fits (its input check allows the 15 features only).
            self.models[mode] = HistGradientBoostingClassifier(
                max_iter=hp.max_iter, max_depth=hp.max_depth, learning_rate=hp.learning_rate,
                min_samples_leaf=hp.min_samples_leaf, l2_regularization=hp.l2_regularization,
                max_bins=hp.max_bins, early_stopping=False, random_state=hp.random_state,
            ).fit(X[modes == mode], falling, sample_weight=w[modes == mode])
        return self

    def scores(self, traj) -> np.ndarray:
        out = np.full(len(traj.mode), -np.inf)          # a mode without falling samples: balanced
        X = self.inputs(traj).X
        for mode, model in self.models.items():
            rows = traj.mode == mode
            if rows.any():
                out[rows] = model if isinstance(model, float) else model.decision_function(X[rows])
        return out



#: The time since the push's onset an input saturates at [s]; before the onset it reads this too.
PUSH_TIME_CAP_S = 2.0


def with_time_since_push(traj):
    """``traj`` with ``X`` (N, 16): the features and the time since the push's onset [s], capped
    at :data:`PUSH_TIME_CAP_S` and at the cap before the onset (no push seen)."""
    since = traj.t - traj.t_push
    since = np.where((since < 0) | (since > PUSH_TIME_CAP_S), PUSH_TIME_CAP_S, since)
    return dataclasses.replace(traj, X=np.hstack([traj.X, since[:, None]]))


class ImuInputs:
    """The 15 features and the IMU tilt detector's four signals (fused roll and pitch [rad], roll
    and pitch rate [rad/s]; NaN where the IMU has no sample) at each feature sample, by
    trajectory id; a mirror image takes its original's signals reflected."""

    def __init__(self) -> None:
        self.signals: dict[str, np.ndarray] = {}

    def add(self, data_dir: Path, trajs, jobs: int) -> None:
        from fall_predictor.learning.tilt_detector import imu_signals_cached
        signals = imu_signals_cached(data_dir, trajs, jobs=jobs, progress=True)
        if signals is None:
            raise ValueError(f'{data_dir}: recorded without the sensor topics, no IMU to read')
        repeated = [t.trajectory_id for t in trajs if t.trajectory_id in self.signals]
        if repeated:
            raise ValueError(f'{data_dir}: trajectory ids already read from another dataset, e.g. '
                             f'{repeated[0]}: one ImuInputs per dataset')
        self.signals.update({t.trajectory_id: s for t, s in zip(trajs, signals)})

    def __call__(self, traj):
        tid = traj.trajectory_id
        if tid.endswith(MIRROR_ID_SUFFIX):
            imu = self.signals[tid[:-len(MIRROR_ID_SUFFIX)]] * ATTITUDE_MIRROR_SIGNS   # roll and roll rate flip, as the base's
        else:
            imu = self.signals[tid]
        return dataclasses.replace(traj, X=np.hstack([traj.X, imu]))


def figures(pooled) -> dict:
    return {'n_balanced': pooled.n_balanced, 'n_false_positives': pooled.n_false_positives,
            'fpr': round(pooled.fpr, 4), 'fpr_ci95': [round(c, 4) for c in pooled.fpr_ci95],
            'n_fallen': pooled.n_fallen, 'tau_lead_s': round(pooled.tau_lead_s, 3),
            'tau_lead_ci95': [round(c, 3) for c in pooled.tau_lead_ci95], 'n_missed': pooled.n_missed}


def cost_us(lists, trajs, n: int = 20000) -> dict:
    """CPU per ``predict_one`` [us] over up to ``n`` test samples, best of three passes."""
    samples = [(list(map(float, x)), int(m)) for t in trajs for x, m in zip(t.X[::25], t.mode[::25])][:n]
    best = np.inf
    for _ in range(3):
        start = time.process_time()
        for x, m in samples:
            lists.predict_one(x, m)
        best = min(best, (time.process_time() - start) / len(samples) * 1e6)
    return {'per_decision_us': round(best, 2), 'samples': len(samples)}


def stratified_subset(trajs: list, n: int, seed: int = 0) -> list:
    """``n`` of ``trajs`` drawn at random (``seed``), fallen and balanced in their shares, in
    their original order."""
    if not 2 <= n <= len(trajs):
        raise ValueError(f'a subset of {n} of {len(trajs)} trajectories')
    rng = np.random.default_rng(seed)
    fallen = np.array([t.fallen for t in trajs])
    n_fallen = round(n * fallen.mean())
    keep = np.concatenate([rng.permutation(np.flatnonzero(fallen))[:n_fallen],
                           rng.permutation(np.flatnonzero(~fallen))[:n - n_fallen]])
    return [trajs[i] for i in sorted(keep.tolist())]


def fixed_arg(text: str) -> tuple[str, tuple[float | None, float, float]]:
    """``LEARNER:THRESHOLD,TAU_HIS[,TAU_PLUS]`` -> (learner, (tau_plus or None, threshold,
    tau_his))."""
    name, _, setting = text.partition(':')
    try:
        values = [float(v) for v in setting.split(',')]
        if len(values) not in (2, 3):
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r}: expected LEARNER:THRESHOLD,TAU_HIS[,TAU_PLUS], '
                                         'e.g. boosting:3.0,0.03 or tree:0,0.06,-0.25') from None
    return name, (values[2] if len(values) == 3 else None, values[0], values[1])


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--data', type=Path, required=True, help='development data')
    parser.add_argument('--test', type=Path, default=None, help='held-out data (optional)')
    parser.add_argument('--folds', type=int, default=5)
    parser.add_argument('--seed', type=int, default=0, help='fold seed (the sweep uses 0)')
    parser.add_argument('--tau-plus', type=float, action='append', default=None,
                        help='training tau_plus [s] (default -0.25); repeatable: a grid, chosen '
                             'with the run-time setting by the same nested CV')
    parser.add_argument('--mirror', action='store_true', help='train both with mirror images')
    parser.add_argument('--thresholds', type=lambda s: tuple(float(v) for v in s.split(',')),
                        default=THRESHOLDS)
    parser.add_argument('--param', type=learner_param, action='append', default=[], metavar='KEY=VALUE',
                        help='boosting hyper-parameter, repeatable (decision_threshold is swept)')
    parser.add_argument('--window', action='store_true',
                        help='also the boosting learner on the features and their changes over '
                             'the last 50, 100 and 200 ms (an offline reference, not shippable)')
    parser.add_argument('--imu', action='store_true',
                        help='also the boosting learner on the features and the IMU tilt '
                             'detector\'s four signals (fused roll and pitch, their rates): '
                             'features from the IMU, an offline reference')
    parser.add_argument('--attitude', action='store_true',
                        help='also the boosting learner on the features and the base\'s attitude '
                             '(method §8c): what `train --attitude` ships')
    parser.add_argument('--push-time', action='store_true',
                        help='also the boosting learner on the features and the time since the '
                             'push\'s onset, which the monitor is never told (a privileged '
                             'reference)')
    parser.add_argument('--fixed', type=fixed_arg, action='append', default=[],
                        metavar='LEARNER:THRESHOLD,TAU_HIS',
                        help='a setting fixed in advance (e.g. a shipped model\'s), reported '
                             'beside the nested choices; repeatable')
    parser.add_argument('--cusum', action='store_true',
                        help="also the boosted trees' scores under the CUSUM rule instead of the "
                             'history window')
    parser.add_argument('--cusum-drifts', type=lambda s: tuple(float(v) for v in s.split(',')),
                        default=CUSUM_DRIFTS, help='the CUSUM drift grid [log-odds]')
    parser.add_argument('--cusum-levels', type=lambda s: tuple(float(v) for v in s.split(',')),
                        default=CUSUM_LEVELS_S, help='the CUSUM level grid [log-odds s]')
    parser.add_argument('--trajectories', type=int, default=None, metavar='N',
                        help='a random subset of N development trajectories, both outcomes in '
                             'their shares (seed 0): a learning curve')
    parser.add_argument('--budgets', type=lambda s: tuple(float(v) for v in s.split(',')),
                        default=BUDGETS, help=f'FPR budgets of the nested choices (default {BUDGETS})')
    parser.add_argument('--fpr-rule', choices=('ucb', 'point'), default='ucb',
                        help='the budget checked on the FPR\'s one-sided Wilson upper bound (ucb) or on '
                             'the pooled FPR (point)')
    parser.add_argument('--fpr-level', type=float, default=0.95, help='level of the ucb rule\'s bound')
    parser.add_argument('--folds-by', choices=('cause_band', 'outcome'), default='cause_band',
                        help='folds grouped by cause and push impulse band, or stratified by outcome')
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    tau_plus_grid = tuple(args.tau_plus or (-0.25,))
    fixed = []
    for name, (tau_plus, threshold, tau_his) in args.fixed:
        if tau_plus is None and len(tau_plus_grid) == 1:
            tau_plus = tau_plus_grid[0]
        if (name not in ('tree', 'boosting') or tau_his not in TAU_HIS_S or tau_plus not in tau_plus_grid
                or (name == 'boosting' and threshold not in args.thresholds)
                or (name == 'tree' and threshold != 0)):
            parser.error(f'--fixed {name}:{threshold},{tau_his}: not a setting of the grid '
                         f'(learner tree or boosting, tau_his in {TAU_HIS_S}, thresholds in '
                         f'{args.thresholds}; the lists: 0; tau_plus in {tau_plus_grid}, '
                         'given when there are several)')
        fixed.append((name, (tau_plus, threshold, tau_his)))
    guard_m = dataset_guard_com_height_m(args.data)
    trajs = load_dataset(args.data, jobs=args.jobs, state='estimated').trajectories
    if args.trajectories is not None:
        trajs = stratified_subset(trajs, args.trajectories)
    learners = {'tree': make_learner('tree'), 'boosting': make_learner('boosting', dict(args.param))}
    if args.window:
        learners['boosting_window'] = ExtraInputsBoosting(dict(args.param), windowed)
    if args.imu:
        imu = ImuInputs()
        imu.add(args.data, trajs, args.jobs)
        learners['boosting_imu'] = ExtraInputsBoosting(dict(args.param), imu)
    if args.push_time:
        learners['boosting_push_time'] = ExtraInputsBoosting(dict(args.param), with_time_since_push)
    if args.attitude:
        learners['boosting_attitude'] = make_learner('boosting', dict(args.param))

    def inputs(name, ts):
        """The trajectories as learner ``name`` reads them (the attitude's: 19 inputs)."""
        return model_inputs(ts, name == 'boosting_attitude')

    def fit(learner, train, tau_plus):
        if isinstance(learner, ExtraInputsBoosting):
            return ExtraInputsBoosting(learner.params, learner.inputs).fit(train, tau_plus, args.mirror)
        return fit_strided(train, tau_plus, learner, mirror=args.mirror)
    if args.folds_by == 'cause_band':
        groups = fold_groups([t.trajectory_id for t in trajs], disturbances(read_index(args.data)),
                             args.folds)
        folds = grouped_trajectory_folds(groups, args.folds, args.seed)
    else:
        folds = stratified_trajectory_folds(trajs, args.folds, args.seed)
    # Per learner, per fold: {(tau_plus, decision threshold, tau_his): result on the fold}.
    rules = list(learners) + (['boosting_cusum'] if args.cusum else [])
    grids = {name: {k: {} for k in range(len(folds))} for name in rules}
    fit_s = {name: 0.0 for name in learners}
    for k, test_index in enumerate(folds):
        train = [trajs[i] for j, f in enumerate(folds) if j != k for i in f]
        test = [trajs[i] for i in test_index]
        for name, learner in learners.items():
            for tau_plus in tau_plus_grid:
                start = time.perf_counter()
                lists = fit(learner, inputs(name, train), tau_plus)
                fit_s[name] += time.perf_counter() - start
                kind = 'tree' if name == 'tree' else 'boosting'
                for thr, results in fold_results(lists, inputs(name, test), kind, args.thresholds,
                                                 guard_m).items():
                    for tau_his, result in results.items():
                        grids[name][k][(tau_plus, thr, tau_his)] = result
                if name == 'boosting' and args.cusum:
                    cusum = cusum_results(lists, inputs(name, test), guard_m, args.cusum_drifts,
                                          args.cusum_levels)
                    for (drift, level), result in cusum.items():
                        grids['boosting_cusum'][k][(tau_plus, drift, level)] = result
        print(f'fold {k} done', flush=True)
    out = {'data': str(args.data), 'trajectories': len(trajs), 'folds': len(folds), 'seed': args.seed,
           'fpr_rule': args.fpr_rule, 'fpr_level': args.fpr_level, 'folds_by': args.folds_by,
           'tau_plus_s': list(tau_plus_grid),
           'mirror': args.mirror, 'boosting_params': learners['boosting'].get_params(),
           'window_lags_s': list(WINDOW_LAGS_S) if args.window else None,
           'imu_inputs': ['fused_roll_rad', 'fused_pitch_rad', 'roll_rate_rad_s', 'pitch_rate_rad_s'] if args.imu else None,
           'attitude_inputs': list(ATTITUDE_NAMES) if args.attitude else None,
           'push_time_cap_s': PUSH_TIME_CAP_S if args.push_time else None,
           'cusum_drifts': list(args.cusum_drifts) if args.cusum else None,
           'cusum_levels_s': list(args.cusum_levels) if args.cusum else None,
           'setting': '(tau_plus [s], decision_threshold [log-odds], tau_his [s]); the lists: '
                      '(tau_plus, 0, tau_his); boosting_cusum: (tau_plus, drift [log-odds], '
                      'level [log-odds s])',
           'fit_s_per_fold_and_tau_plus': {n: round(s / len(folds) / len(tau_plus_grid), 1)
                                           for n, s in fit_s.items()},
           'nested': {}, 'fixed': {}, 'test': None}
    chosen_on_dev = {}
    for name in rules:
        out['nested'][name] = {}
        for budget in args.budgets:
            point = nested_over_grid(grids[name], budget, args.fpr_rule, args.fpr_level)
            out['nested'][name][str(budget)] = {'chosen_per_fold': point.chosen, **figures(point.outer),
                                                'chosen_on_all_folds': point.selected_in_hindsight}
            chosen_on_dev[(name, budget)] = point.selected_in_hindsight
            print(name, budget, out['nested'][name][str(budget)], flush=True)
    for name, setting in fixed:
        key = f'{name}:{setting[1]},{setting[2]},{setting[0]}'
        out['fixed'][key] = figures(pool_results([grids[name][k][setting] for k in sorted(grids[name])]))
        print('fixed', key, out['fixed'][key], flush=True)
    if args.test is not None:
        test = load_dataset(args.test, jobs=args.jobs, state='estimated').trajectories
        test_guard_m = dataset_guard_com_height_m(args.test)
        if args.imu:                                    # trajectory ids repeat across datasets
            test_imu = ImuInputs()
            test_imu.add(args.test, test, args.jobs)
        out['test'] = {'data': str(args.test), 'learners': {}}
        final_boosting = {}             # tau_plus -> the boosted trees on all the development data
        for name, learner in learners.items():
            kind = 'tree' if name == 'tree' else 'boosting'
            needed = sorted({chosen_on_dev[(name, b)][0] for b in args.budgets}
                            | {setting[0] for n, setting in fixed if n == name})
            row, results = {}, {}
            for tau_plus in needed:
                lists = fit(learner, inputs(name, trajs), tau_plus)
                if name == 'boosting':
                    final_boosting[tau_plus] = lists
                if isinstance(getattr(lists, 'inputs', None), ImuInputs):
                    lists.inputs = test_imu             # the trained model reads the test set's IMU
                results[tau_plus] = fold_results(lists, inputs(name, test), kind, args.thresholds,
                                                 test_guard_m)
                if hasattr(lists, 'mean_rule_size'):
                    row[f'tau_plus:{tau_plus}'] = {'mean_rule_size': lists.mean_rule_size,
                                                   'cost': cost_us(lists, inputs(name, test))}
            for budget in args.budgets:
                tau_plus, thr, tau_his = chosen_on_dev[(name, budget)]
                payload = evaluation_result_json(results[tau_plus][thr][tau_his])
                row[str(budget)] = {'tau_plus_s': tau_plus, 'decision_threshold': thr, 'tau_his_s': tau_his,
                                    **{k: payload[k] for k in KEEP if k in payload}}
                print(name, budget, row[str(budget)], flush=True)
            for fixed_name, (tau_plus, thr, tau_his) in fixed:
                if fixed_name == name:
                    payload = evaluation_result_json(results[tau_plus][thr][tau_his])
                    key = f'fixed:{thr},{tau_his},{tau_plus}'
                    row[key] = {k: payload[k] for k in KEEP if k in payload}
                    print(name, 'fixed', (thr, tau_his, tau_plus), row[key], flush=True)
            out['test']['learners'][name] = row
        if args.cusum:
            # The CUSUM rule on the same final boosted trees (fitted above where a budget of the
            # history window chose the same tau_plus), at each budget's chosen setting only.
            row = {}
            for budget in args.budgets:
                tau_plus, drift, level = chosen_on_dev[('boosting_cusum', budget)]
                if tau_plus not in final_boosting:
                    final_boosting[tau_plus] = fit(learners['boosting'], inputs('boosting', trajs),
                                                   tau_plus)
                result = cusum_results(final_boosting[tau_plus], inputs('boosting', test),
                                       test_guard_m, (drift,), (level,))[(drift, level)]
                payload = evaluation_result_json(result)
                row[str(budget)] = {'tau_plus_s': tau_plus, 'drift': drift, 'level_s': level,
                                    **{k: payload[k] for k in KEEP if k in payload}}
                print('boosting_cusum', budget, row[str(budget)], flush=True)
            out['test']['learners']['boosting_cusum'] = row
    text = json.dumps(out, indent=1, default=float)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + '\n')
    return out


if __name__ == '__main__':
    main()
