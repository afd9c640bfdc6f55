"""The sweep's written results: ``sweep.json`` (:func:`sweep_json`) and ``table.md``
(:func:`sweep_table`, the Table 2 analogue next to the paper, the baselines' fronts, the
learning curve and every point of the grid). The figures are in
:mod:`fall_predictor.learning.plots`.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Optional

from fall_predictor.learning.baselines import pareto_front
from fall_predictor.learning.crossval import SweepPoint
from fall_predictor.learning.evaluation import curve_point_json, evaluation_result_json, json_float
from fall_predictor.learning.nested import nested_report_json, nested_table_lines
from fall_predictor.learning.selection import (PAPER_PREDICTORS, PARETO_MAX_FPR, SELECTION_RULE,
                                              pareto_mean_lead)
from fall_predictor.learning.sweep_results import SweepResult
from fall_predictor.learning.training import make_learner


def _point_json(point: SweepPoint, with_folds: bool = True) -> dict[str, Any]:
    """A cross-validated point (NaN and infinity -> null), with its fold results or not."""
    payload = {key: (json_float(value) if isinstance(value, float) else value)
               for key, value in dataclasses.asdict(point).items() if key != 'per_fold'}
    payload['n_pre_push_alarms'] = point.n_pre_push_alarms
    if with_folds:
        payload['per_fold'] = [evaluation_result_json(r) for r in point.per_fold]
    return payload


def _nested(result: SweepResult) -> Optional[dict[str, Any]]:
    """method §11 nested points and the paper's fixed settings, from the sweep's grid trainings."""
    return nested_report_json(
        [fit for fit in result.fits if fit.train_size is None
         and fit.tau_plus_s in result.config.tau_plus_values_s],
        {p.name: (p.tau_plus_s, p.tau_his_s) for p in PAPER_PREDICTORS})


def sweep_json(result: SweepResult) -> dict[str, Any]:
    """The ``sweep.json`` document (NaN and infinity written as null)."""
    front = {(p.tau_plus_s, p.tau_his_s) for p in result.pareto}
    return {
        'format': 'fall_predictor/sweep/v1',
        'command': result.command,
        'dataset': {'path': result.data_dir, 'fingerprint': result.dataset_fingerprint,
                    'n_trajectories': result.n_trajectories, 'n_fallen': result.n_fallen,
                    'n_balanced': result.n_trajectories - result.n_fallen,
                    'unreadable': result.unreadable},
        'settings': result.config.as_json(),
        'points': [{**_point_json(p), 'pareto': (p.tau_plus_s, p.tau_his_s) in front}
                   for p in result.points],
        'selected': [{'name': paper.name, 'paper': dataclasses.asdict(paper),
                      'ours': _point_json(point, with_folds=False)}
                     for paper, point in result.selected],
        'selection_rule': SELECTION_RULE,
        'pareto_mean_lead_s': {
            'max_fpr': PARETO_MAX_FPR, 'learned': json_float(pareto_mean_lead(result.points)),
            **{f'baseline_{name}': json_float(pareto_mean_lead(curve))
               for name, curve in result.baselines.named().items()}},
        'nested_selection': _nested(result),
        'baselines_nested': result.baselines_nested,
        'learning_curve': [_point_json(p) for p in result.learning_curve],
        'trainings': [{'fold': fit.fold, 'tau_plus_s': fit.tau_plus_s, 'n_train': fit.n_train,
                       'fit_s': fit.fit_s, 'mean_rule_size': fit.mean_rule_size,
                       'rule_sizes': list(fit.rule_sizes), 'depths': list(fit.depths)}
                      for fit in result.fits],
        'baselines': {name: [curve_point_json(p) for p in curve]
                      for name, curve in result.baselines.named().items()},
        'timing': dataclasses.asdict(result.timing),
        'files': list(result.files),
    }


def _fmt(value: Optional[float], digits: int = 3) -> str:
    return '—' if value is None or (isinstance(value, float) and math.isnan(value)) \
        else f'{value:.{digits}f}'


def sweep_table(result: SweepResult) -> str:
    """``table.md``: the Table 2 analogue next to the paper, then every point of the grid."""
    c = result.config
    lines = [
        '# Cross-validated sweep', '',
        f'Dataset `{result.data_dir}`: {result.n_trajectories} trajectories, {result.n_fallen} '
        f'fallen (fingerprint `{result.dataset_fingerprint}`). {c.folds}-fold cross-validation by '
        f'trajectory (seed {c.seed}); learner `{c.learner_name}` '
        f'{make_learner(c.learner_name, c.learner_params).get_params()}, sample stride '
        f'{c.sample_stride}' + (', trained with mirror images' if c.mirror else '') + '. FPR, tau_lead and lead fraction are means over folds; misses and '
        'pre-push alarms are totals.' + (f' Command: `{result.command}`.' if result.command else ''), '',
        '## Table 2 analogue', '',
        f'Selection rule: {SELECTION_RULE}.', '',
        '| | ' + ' | '.join(f'{paper.name} (paper) | ours' for paper, _ in result.selected) + ' |',
        '|---|' + '---|---|' * len(result.selected)]
    rows = [('tau_plus [s]', lambda p: p.tau_plus_s, 2), ('tau_his [s]', lambda p: p.tau_his_s, 3),
            ('FPR', lambda p: p.fpr, 3), ('tau_lead [s]', lambda p: p.tau_lead_s, 2),
            ('mean rule size', lambda p: p.mean_rule_size, 1)]
    for label, get, digits in rows:
        lines.append(f'| {label} | ' + ' | '.join(f'{_fmt(get(paper), digits)} | {_fmt(get(point), digits)}'
                                                   for paper, point in result.selected) + ' |')
    lines.append('| misses / fallen | ' + ' | '.join(f'— | {p.n_missed}/{p.n_fallen}'
                                                     for _, p in result.selected) + ' |')
    lines.append('| lead fraction | ' + ' | '.join(f'— | {_fmt(p.lead_fraction, 2)}'
                                                   for _, p in result.selected) + ' |')
    lines += nested_table_lines(_nested(result))
    lines += _nested_baseline_lines(result.baselines_nested)
    lines += ['', f'Mean best tau_lead over FPR budgets in [0, {PARETO_MAX_FPR}] (area under the '
              f'Pareto front / {PARETO_MAX_FPR}): learned {_fmt(pareto_mean_lead(result.points))} s; '
              + ', '.join(f'{name} {_fmt(pareto_mean_lead(curve))} s'
                          for name, curve in result.baselines.named().items()) + '.',
              '', '## Baselines (Pareto fronts over their thresholds, all trajectories)', '',
              'Each threshold is one predictor evaluated on every trajectory (no cross-validation: '
              'the front picks thresholds in hindsight). Paper: CoM height at FPR 0 gives tau_lead '
              '0.14 s, tau_lead 0.42 s costs FPR 0.92; momentum thresholds at best FPR 0.11 with '
              'tau_lead 0.60 s.', '',
              '| baseline | threshold | FPR | tau_lead [s] | misses |', '|---|---|---|---|---|']
    for name, curve in result.baselines.named().items():
        for point in pareto_front(curve):
            threshold = point.threshold
            text = (', '.join(_fmt(v, 3) if math.isfinite(v) else 'inf' for v in threshold)
                    if isinstance(threshold, tuple) else _fmt(threshold, 3))
            lines.append(f'| {name} | {text} | {_fmt(point.fpr)} | {_fmt(point.tau_lead_s, 2)} | '
                         f'{point.evaluation.n_missed} |')
    if result.learning_curve:
        lines += ['', f'## Learning curve (tau_plus {c.learning_curve_tau_plus_s} s, tau_his '
                  f'{c.learning_curve_tau_his_s} s)', '',
                  '| training trajectories | FPR | tau_lead [s] | mean rule size |', '|---|---|---|---|']
        for p in result.learning_curve:
            lines.append(f'| {p.n_train:.0f} | {_fmt(p.fpr)} ± {_fmt(p.fpr_std)} | '
                         f'{_fmt(p.tau_lead_s, 2)} ± {_fmt(p.tau_lead_std_s, 2)} | '
                         f'{_fmt(p.mean_rule_size, 1)} |')
    front = {(p.tau_plus_s, p.tau_his_s) for p in result.pareto}
    lines += ['', '## All predictors (* = Pareto front)', '',
              '| tau_plus [s] | tau_his [s] | FPR | tau_lead [s] | misses | pre-push alarms | '
              'oracle lead [s] | lead fraction | mean rule size | mean depth |',
              '|---|---|---|---|---|---|---|---|---|---|']
    for p in result.points:
        star = '*' if (p.tau_plus_s, p.tau_his_s) in front else ''
        lines.append(f'| {p.tau_plus_s:+.2f}{star} | {p.tau_his_s:.3f} | {_fmt(p.fpr)} | '
                     f'{_fmt(p.tau_lead_s, 2)} | {p.n_missed} | {p.n_pre_push_alarms} | '
                     f'{_fmt(p.oracle_lead_s, 2)} | {_fmt(p.lead_fraction, 2)} | '
                     f'{_fmt(p.mean_rule_size, 1)} | {_fmt(p.mean_depth, 1)} |')
    t = result.timing
    lines += ['', f'Wall times: total {t.total_s:.0f} s with {t.jobs} job(s); loading {t.load_s:.0f} s, '
              f'capture point {t.capture_point_s:.0f} s, baselines {t.baselines_s:.0f} s, '
              f'cross-validation {t.cross_validation_s:.0f} s ({t.n_fits} trainings, mean full-size '
              f'fit {t.fit_s_mean_full:.2f} s), plots {t.plots_s:.0f} s.', '']
    return '\n'.join(lines)


def _nested_baseline_lines(document: Optional[dict[str, Any]]) -> list[str]:
    """The baselines chosen like the learned lists: threshold and tau_his on training folds."""
    if not document:
        return []
    lines = ['', '## Baselines, nested (threshold and tau_his chosen on the training folds)', '',
             '| baseline | FPR budget | FPR [95 % CI] | tau_lead [s] [95 % CI] | misses |',
             '|---|---|---|---|---|']
    for name, entries in document.items():
        for entry in entries:
            o = entry['outer']
            if o.get('fpr') is None or o.get('tau_lead_s') is None:
                figures = '— | —'
            else:
                figures = (f"{o['fpr']:.3f} [{o['fpr_ci95'][0]:.3f}, {o['fpr_ci95'][1]:.3f}] | "
                           f"{o['tau_lead_s']:.2f} [{o['tau_lead_ci95'][0]:.2f}, {o['tau_lead_ci95'][1]:.2f}]")
            lines.append(f"| {name} | ≤ {entry['max_fpr']} | {figures} | {o['n_missed']}/{o['n_fallen']} |")
    return lines
