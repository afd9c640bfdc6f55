"""``fall-predictor train``, ``rules``, ``evaluate``, ``fit-direction`` and ``fit-time-to-fall``:
models."""
from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

from fall_predictor.cli import args as argtypes
from fall_predictor.cli.args import emit as _emit, fail as _fail


def cmd_train(args) -> int:
    from fall_predictor.data.dataset import DatasetError
    from fall_predictor.learning.training import make_learner
    from fall_predictor.learning.window_choice import WindowSearch, train_choosing_window
    from fall_predictor.monitor.model_file import ModelFileError, save_model

    try:
        make_learner(args.learner, dict(args.param))
        chosen_by = {name: value for name, value in (('max_fpr', args.max_fpr), ('folds', args.folds),
                                                     ('decision_thresholds', args.decision_thresholds),
                                                     ('tau_his_values_s', args.tau_his_grid),
                                                     ('fpr_rule', args.fpr_rule),
                                                     ('fpr_level', args.fpr_level),
                                                     ('folds_by', args.folds_by))
                     if value is not None}
        search = WindowSearch(**chosen_by)
    except ValueError as error:
        return _fail('train', error)
    start = time.perf_counter()
    try:
        for data in args.data:                 # says so when a dataset has no sensor topics
            argtypes.resolved_state(argparse.Namespace(data=data, state=args.state))
        trained = train_choosing_window(args.data, args.tau_plus, args.learner, dict(args.param),
                                        args.stride, jobs=args.jobs, tau_his_s=args.tau_his,
                                        search=search, skip_unreadable=args.skip_unreadable,
                                        progress=not args.json, state=args.state,
                                        mirror=args.mirror, attitude=args.attitude)
        lists, metadata, window = trained.lists, trained.metadata, trained.window
        save_model(args.out, lists, metadata)
    except (DatasetError, ModelFileError, ValueError) as error:
        return _fail('train', error)
    wall = time.perf_counter() - start
    refused = trained.report.refused_total
    payload = {'model': str(args.out), 'tau_plus_s': metadata.tau_plus_s,
               'recommended_tau_his_s': metadata.recommended_tau_his_s,
               'tau_his_chosen': None if window is None else window.to_json(),
               'tau_his_not_chosen': trained.not_chosen,
               'refused_samples': refused.total,
               'learner': {'name': metadata.learner_name, 'params': metadata.learner_params},
               'sample_stride': args.stride, 'state': metadata.state, 'mirror': metadata.mirror,
               'n_inputs': lists.n_inputs,
               'guard_com_height_m': metadata.feature_settings.guard_com_height_m,
               'dataset_fingerprint': metadata.dataset_fingerprint,
               'datasets': [part.to_json() for part in trained.datasets],
               'n_trajectories': len(trained.report.trajectories),
               'robot_mass_kg': metadata.robot_mass_kg,
               'mean_rule_size': lists.mean_rule_size, 'rule_sizes': list(lists.rule_sizes),
               'depths': list(lists.depths), 'wall_s': wall}
    lines = [f'wrote {args.out}: {metadata.learner_name} on the {metadata.state} state, tau_plus '
             f'{metadata.tau_plus_s:+.3f} s, stride {args.stride}, mean rule size '
             f'{lists.mean_rule_size:.1f}, depths {list(lists.depths)} ({wall:.1f} s)',
             f'trained on {len(trained.report.trajectories)} trajectories: '
             + '; '.join(f'{part.n_trajectories} ({part.n_fallen} fallen) from {part.data_dir}'
                         + (f' as {part.prefix}/...' if part.prefix else '')
                         for part in trained.datasets)]
    if trained.not_chosen is not None:
        lines.append(f'no tau_his stored: {trained.not_chosen}')
    elif window is None:
        lines.append(f'tau_his {metadata.recommended_tau_his_s:.3f} s (given), stored in the model')
    else:
        from fall_predictor.learning.nested import fpr_bound, fpr_rule_text
        chosen = window.chosen
        search = window.search
        bound = fpr_bound(chosen, search.fpr_rule, search.fpr_level)
        if window.decision_threshold is not None:
            lines.append(f'decision threshold {window.decision_threshold:g} chosen with the window, '
                         f'among {", ".join(f"{d:g}" for d in window.search.decision_thresholds)}')
        folds_by = ('grouped by cause and push impulse band' if search.folds_by == 'cause_band'
                    else 'stratified by outcome')
        lines.append(f'tau_his {window.tau_his_s:.3f} s chosen by {window.folds}-fold cross-validation '
                     f'on this data, folds {folds_by} (the longest lead where '
                     f'{fpr_rule_text(search.fpr_rule, search.fpr_level)} is <= {search.max_fpr:g}): '
                     f'FPR {chosen.fpr:.3f} ({chosen.n_false_positives}/{chosen.n_balanced})'
                     + (f', upper bound {bound:.3f}' if search.fpr_rule == 'ucb' else '')
                     + f', tau_lead {chosen.tau_lead_s:.3f} s, misses {chosen.n_missed}/'
                     f'{chosen.n_fallen}; stored in the model')
        if not window.within_budget:
            lines.append(f'warning: no window met the budget {search.max_fpr:g} on held-out folds '
                         f'({fpr_rule_text(search.fpr_rule, search.fpr_level)}): the one with the '
                         'lowest was chosen'
                         + (f'; {chosen.n_balanced} survived runs cannot show an FPR below '
                            f'{fpr_bound(dataclasses.replace(chosen, n_false_positives=0), "ucb", search.fpr_level):.3f}'
                            ' even without a false alarm: more runs that do not fall'
                            if search.fpr_rule == 'ucb' else ''))
    if refused.total:
        lines.append(f'{refused.total} samples refused ({refused.estimator} by the estimator, '
                     f'{refused.features} by the feature extractor): left out as holes, as onboard')
    _emit(args, payload, lines)
    return 0


def cmd_rules(args) -> int:
    from fall_predictor.learning.training import rules_summary
    from fall_predictor.monitor.model_file import ModelFileError, load_model

    try:
        lists, metadata = load_model(args.model)
    except ModelFileError as error:
        return _fail('rules', error)
    summary = rules_summary(lists)
    payload = {'model': str(args.model), **summary,
               'training': {'tau_plus_s': metadata.tau_plus_s, 'learner': metadata.learner_name,
                            'params': metadata.learner_params,
                            'recommended_tau_his_s': metadata.recommended_tau_his_s}}
    lines = [f'# {args.model}: {metadata.learner_name}, tau_plus {metadata.tau_plus_s:+.3f} s']
    for mode in summary['modes']:
        lines += ['', f'# {mode["mode"]}: rule size {mode["rule_size"]}, depth {mode["depth"]}', mode['text']]
    lines += ['', f'mean rule size {summary["mean_rule_size"]:.2f} (over the 16 modes); mean depth '
                  f'{summary["mean_depth"]:.1f} (non-empty lists), max depth {summary["max_depth"]}']
    _emit(args, payload, lines)
    return 0


def cmd_evaluate(args) -> int:
    from fall_predictor.data.dataset import DatasetError, dataset_guard_com_height_m
    from fall_predictor.learning.deployment import deployment_lines
    from fall_predictor.learning.evaluation import evaluate_model, evaluation_json
    from fall_predictor.learning.when_where import when_where_lines
    from fall_predictor.monitor.model_file import ModelFileError, load_model

    try:
        lists, metadata = load_model(args.model)
        tau_his = args.tau_his if args.tau_his is not None else metadata.recommended_tau_his_s
        if tau_his is None:
            return _fail('evaluate', f'{args.model} recommends no tau_his: give --tau-his')
        if args.decision_threshold is not None:
            try:
                lists = lists.with_decision_threshold(args.decision_threshold)
            except ValueError as error:
                return _fail('evaluate', f'--decision-threshold: {args.model}: {error}')
        state = argtypes.resolved_state(args)
        if metadata.state is not None and state != metadata.state and state != args.state:
            # A dataset without sensor topics fell back to the true state: the figures would be
            # those of another input than the model runs on onboard, silently.
            return _fail('evaluate', f'{args.model} was trained on the {metadata.state} state, but '
                         f'{args.data} was recorded without sensor topics, so its features would come '
                         f'from the {state} state and the figures would not be the model\'s: record '
                         'them (`generate --sensor-noise 1`), or give --state true to evaluate so')
        evaluation = evaluate_model(args.data, lists, tau_his, baselines=args.baselines,
                                    jobs=args.jobs, skip_unreadable=args.skip_unreadable,
                                    progress=not args.json, time_to_fall=metadata.time_to_fall,
                                    robot_mass_kg=metadata.robot_mass_kg, state=state,
                                    guard_com_height_m=metadata.feature_settings.guard_com_height_m,
                                    fall_direction=metadata.fall_direction)
        dataset_guard = dataset_guard_com_height_m(args.data)
        per_run = None
        if args.per_run is not None:
            from fall_predictor.learning.per_run import write_per_run
            per_run = write_per_run(args.per_run, evaluation.run_records(), {
                'model': str(args.model), 'data': str(args.data), 'state': state,
                'tau_his_s': tau_his, 'guard_com_height_m': evaluation.guard_com_height_m})
    except (DatasetError, ModelFileError) as error:
        return _fail('evaluate', error)
    except OSError as error:
        return _fail('evaluate', f'--per-run {args.per_run}: {error}')
    payload = {'model': str(args.model), 'data': str(args.data), 'state': state,
               'model_state': metadata.state, 'decision_threshold': lists.decision_threshold,
               **evaluation_json(evaluation, args.band_width),
               'trained_on_this_dataset': metadata.dataset_fingerprint == evaluation.dataset_fingerprint,
               'dataset_guard_com_height_m': dataset_guard,
               'per_run': None if per_run is None else str(per_run)}
    r = evaluation.result
    lines = [f'{r.n_trajectories} trajectories ({r.n_fallen} fallen), {state} state (model trained on '
             f'the {metadata.state} state), tau_his {tau_his:.3f} s'
             + ('' if lists.decision_threshold is None
                else f', decision threshold {lists.decision_threshold:g}')
             + ', the model\'s CoM guard '
             f'{evaluation.guard_com_height_m:g} m',
             f'FPR {r.fpr:.3f} ({r.n_false_positives}/{r.n_balanced} balanced trajectories), '
             f'Wilson 95 % [{r.fpr_ci95[0]:.3f}, {r.fpr_ci95[1]:.3f}]',
             f'tau_lead {r.tau_lead_s:.3f} s (bootstrap 95 % [{r.tau_lead_ci95[0]:.3f}, '
             f'{r.tau_lead_ci95[1]:.3f}]), oracle lead {r.oracle_lead_s:.3f} s, lead fraction '
             f'{r.lead_fraction:.2f}, misses {r.n_missed}/{r.n_fallen}',
             f'decision lists alone (CoM guard off): tau_lead {r.tau_lead_lists_only_s:.3f} s, '
             f'misses {r.n_missed_lists_only}/{r.n_fallen}; CoM guard alone: tau_lead '
             f'{r.tau_lead_guard_only_s:.3f} s',
             f'pre-push false alarms: {r.n_pre_push_alarms} runs alarmed before their push '
             f'({r.n_pre_push_alarms_balanced} balanced, {r.n_pre_push_alarms_fallen} fallen trajectories)'
             + (f'; {payload["n_runs_push_time_unknown"]} runs without a push time (alarms counted '
                'from their start)' if payload['n_runs_push_time_unknown'] else ''),
             f'mean rule size {r.mean_rule_size:.2f}']
    lines += deployment_lines(payload['deployment'])
    if payload['refused_samples']:
        lines.append(f'{payload["refused_samples"]} samples refused ({payload["refused_samples_estimator"]} '
                     f'by the estimator, {payload["refused_samples_features"]} by the feature extractor) '
                     f'in {len(evaluation.refused)} runs: holes, as onboard (a DEGRADED state)')
    if per_run is not None:
        lines.append(f'per run: {per_run}')
    lines += when_where_lines(payload)
    if payload['trained_on_this_dataset']:
        lines.append('warning: the model was trained on this dataset; these numbers are not a '
                     'held-out estimate (use `fall-predictor sweep` for cross-validation)')
    if abs(dataset_guard - evaluation.guard_com_height_m) > 1e-9:
        lines.append(f'warning: the model\'s CoM guard ({evaluation.guard_com_height_m:g} m) is not the '
                     f'dataset\'s robot\'s ({dataset_guard:g} m): a model trained on another robot, or '
                     'before models recorded their robot\'s guard (retrain it)')
    for name, front in payload.get('baselines', {}).items():
        lines.append(f'baseline {name}, Pareto front (FPR, tau_lead): ' + ', '.join(
            f'({p["fpr"]:.2f}, {p["tau_lead_s"]:.2f})' for p in front
            if p['fpr'] is not None and p['tau_lead_s'] is not None))
    for tid, error in evaluation.unreadable.items():
        lines.append(f'SKIPPED {tid}: {error}')
    _emit(args, payload, lines)
    return 0


def _model_and_development_data(args):
    """For the fits at a model's triggers: the model of ``args.model`` (lists, metadata), its
    recommended tau_his, the state and the loaded dataset of ``args.data``. ValueError if the
    model recommends no tau_his (its triggers are then not defined)."""
    from fall_predictor.learning.training import load_dataset
    from fall_predictor.monitor.model_file import load_model

    lists, metadata = load_model(args.model)
    tau_his = metadata.recommended_tau_his_s
    if tau_his is None:
        raise ValueError(f'{args.model} recommends no tau_his: its triggers are not defined')
    state = argtypes.resolved_state(args)
    report = load_dataset(args.data, args.jobs, progress=not args.json, state=state)
    return lists, metadata, tau_his, state, report


def cmd_fit_direction(args) -> int:
    import dataclasses

    import numpy as np

    from fall_predictor.data.dataset import DatasetError
    from fall_predictor.learning.direction_training import fit_learned_direction, trigger_samples
    from fall_predictor.learning.when_where import direction_errors_deg
    from fall_predictor.monitor.fall_direction import momentum_direction
    from fall_predictor.monitor.model_file import ModelFileError, save_model

    try:
        lists, metadata, tau_his, state, report = _model_and_development_data(args)
        samples = trigger_samples(args.data, report.trajectories, lists, tau_his,
                                  metadata.feature_settings.guard_com_height_m)
        if samples.X.shape[0] == 0:
            return _fail('fit-direction', f'{args.data}: the model triggers on no fall with a true '
                                          'CoM to learn from (a recorded robot has none)')
        learned = fit_learned_direction(samples, mirror=not args.no_mirror)
        save_model(args.out, lists, dataclasses.replace(metadata, fall_direction=learned))
    except (DatasetError, ModelFileError, ValueError) as error:
        return _fail('fit-direction', error)
    momentum, fitted = (direction_errors_deg(samples, d) for d in (momentum_direction, learned.direction))
    payload = {'model': str(args.out), 'from_model': str(args.model), 'data': str(args.data),
               'state': state, 'tau_his_s': tau_his, 'mirror': not args.no_mirror,
               'triggers': int(samples.X.shape[0]), 'trees': len(learned.trees),
               'in_sample_median_error_deg': {'momentum': float(np.median(momentum)),
                                              'learned': float(np.median(fitted))}}
    _emit(args, payload, [
        f'wrote {args.out}: a learned fall direction ({len(learned.trees)} trees) fitted at '
        f'{samples.X.shape[0]} triggers of {args.model} on {args.data} ({state} state)',
        f'median error at those triggers (in sample): momentum {np.median(momentum):.1f} deg, '
        f'learned {np.median(fitted):.1f} deg; evaluate it on held-out data'])
    return 0


def cmd_fit_time_to_fall(args) -> int:
    import dataclasses

    import numpy as np

    from fall_predictor.data.dataset import DatasetError
    from fall_predictor.learning.time_to_fall_training import (fit_boosted_time_to_fall,
                                                               time_left_after_triggers)
    from fall_predictor.learning.when_where import trigger_indices
    from fall_predictor.monitor.model_file import ModelFileError, save_model

    try:
        lists, metadata, tau_his, state, report = _model_and_development_data(args)
        triggers = trigger_indices(report.trajectories, lists, tau_his,
                                   metadata.feature_settings.guard_com_height_m)
        X, _, left, at_trigger = time_left_after_triggers(report.trajectories, triggers)
        if not at_trigger.any():
            return _fail('fit-time-to-fall', f'{args.data}: the model triggers on no fall to '
                                              'learn from')
        boosted = fit_boosted_time_to_fall(X, left)
        save_model(args.out, lists, dataclasses.replace(metadata, time_to_fall=boosted))
    except (DatasetError, ModelFileError, ValueError) as error:
        return _fail('fit-time-to-fall', error)
    error = np.abs(np.array([boosted.predict_one(x.tolist()) for x in X[at_trigger]])
                   - left[at_trigger])
    payload = {'model': str(args.out), 'from_model': str(args.model), 'data': str(args.data),
               'state': state, 'tau_his_s': tau_his, 'triggers': int(at_trigger.sum()),
               'samples': int(left.size), 'trees': len(boosted.trees),
               'in_sample_median_error_at_triggers_s': float(np.median(error))}
    _emit(args, payload, [
        f'wrote {args.out}: a time to fall of {len(boosted.trees)} boosted trees fitted on '
        f'{left.size} samples from {int(at_trigger.sum())} triggers of {args.model} until fallen '
        f'on {args.data} ({state} state)',
        f'median error at those triggers (in sample): {np.median(error):.3f} s; evaluate it on '
        'held-out data'])
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser('train', help='learn per-mode decision lists and write a model file',
                       description='Train one decision list per foot contact mode (method §8) on every '
                                   'trajectory of one or more datasets (--data repeated: the same '
                                   'robot\'s, e.g. under two walking controllers or from several '
                                   'sessions) and write the JSON model file. Falling states '
                                   'before t_height_drop + tau_plus are withheld; balanced states weigh 4, '
                                   'falling states 1 (per 1 kHz sample). The history window tau_his the '
                                   'model runs with is chosen by cross-validation on the same data unless '
                                   'given (--tau-his) and stored in the model. Exit code 2 if a dataset or '
                                   'a setting cannot be used, or the datasets disagree (state, CoM '
                                   'guard, feature settings, robot mass).')
    p.add_argument('--data', type=Path, action='append', required=True, metavar='DIR',
                   help='dataset directory; repeat it to train one model on several datasets (each '
                        'from its own feature cache; their state, CoM guard and feature settings '
                        'must agree and their robot masses within 5 %%: the model stores the mean)')
    p.add_argument('--tau-plus', type=argtypes.finite(float), required=True,
                   help='tau_plus [s]: falling states are trained on from t_height_drop + tau_plus '
                        '(may be < 0; write --tau-plus=-0.25)')
    p.add_argument('--out', type=Path, required=True, help='model file to write (JSON)')
    argtypes.add_learner_arguments(p)
    argtypes.add_state_argument(p)
    p.add_argument('--mirror', action='store_true',
                   help='also learn from each trajectory\'s left-right mirror image (modes, y components '
                        'and signs mirrored)')
    p.add_argument('--attitude', action='store_true',
                   help='the classifiers also read the floating base\'s attitude (fused roll and '
                        'pitch, its angular velocity about x and y: method §8c); boosted trees only')
    p.add_argument('--tau-his', '--tau-his-recommended', dest='tau_his', type=argtypes.nonnegative,
                   default=None, metavar='SECONDS',
                   help='history window [s] stored as the model\'s run-time default (default: chosen '
                        'by cross-validation on the --data trajectories, the longest lead at FPR <= '
                        '--max-fpr, as the sweep chooses operating points)')
    p.add_argument('--max-fpr', type=argtypes.finite(float), default=None, metavar='FPR',
                   help='FPR budget of the window\'s choice (default 0.06, FP-L2\'s), on the survived '
                        'runs of the training data\'s distribution (checked by --fpr-rule)')
    p.add_argument('--fpr-rule', choices=('ucb', 'point'), default=None,
                   help='how --max-fpr is checked: on the one-sided Wilson upper bound of the '
                        'cross-validated FPR at --fpr-level (ucb, the default: the budget holds on runs '
                        'the model never saw) or on the cross-validated FPR itself (point: optimistic)')
    p.add_argument('--fpr-level', type=argtypes.finite(float), default=None, metavar='LEVEL',
                   help='confidence level of the ucb rule\'s bound (default 0.95)')
    p.add_argument('--folds-by', choices=('cause_band', 'outcome'), default=None,
                   help='the window\'s folds: grouped by cause and push impulse band (cause_band, the '
                        'default: no fold is tested on a band or cause its training saw) or stratified '
                        'by outcome (outcome, as the sweep)')
    p.add_argument('--folds', type=argtypes.at_least_two, default=None,
                   help='cross-validation folds of the window\'s choice, each one more training '
                        '(default 10; at most one per trajectory)')
    p.add_argument('--decision-thresholds', type=lambda text: tuple(float(v) for v in text.split(',')),
                   default=None, metavar='D1,D2,...',
                   help='boosted trees: choose the decision threshold [log-odds] among these with the '
                        'window, by the same cross-validation (e.g. 0,1,2,3,4,5,6); default: the '
                        'learner\'s own (--param decision_threshold=...)')
    p.add_argument('--tau-his-grid', type=argtypes.list_of(argtypes.nonnegative), default=None, metavar='S1,S2,...',
                   help='the history windows [s] the choice is made among (default: the sweep\'s grid, '
                        '0 to 0.1 s); windows cost no training, only their evaluation')
    p.add_argument('--jobs', type=argtypes.positive_int, default=1,
                   help='processes loading features and training the window\'s folds')
    p.add_argument('--skip-unreadable', action='store_true',
                   help='leave out unreadable bags (of every dataset) instead of failing')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.set_defaults(func=cmd_train)

    p = sub.add_parser('rules', help='print a model\'s decision lists (the paper\'s Fig. 8 form)',
                       description='Print the decision list of every foot contact mode of a model file '
                                   'in the paper\'s Fig. 8 form, with each list\'s rule size (number of '
                                   'comparisons) and depth (number of rules), and the mean rule size over '
                                   'the 16 modes. Exit code 2 if the file is not a valid model.')
    p.add_argument('model', type=Path, help='model file (JSON)')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.set_defaults(func=cmd_rules)

    p = sub.add_parser('evaluate', help='FPR, lead time and misses of a model on a dataset',
                       description='Run a model over every trajectory of a dataset (the online predictor: '
                                   'decision lists, history window tau_his, the model\'s CoM guard) and report '
                                   'method §5\'s '
                                   'metrics: FPR, tau_lead, misses, pre-push false alarms, oracle lead, lead '
                                   'fraction and mean rule size; per cause (push, trip, slip, step, fault): '
                                   'falls caught, FPR over the survived runs, alarms before the onset, '
                                   'lead and lead / onset-to-fall; false alarms per hour of undisturbed '
                                   'walking (Garwood interval); the FPR of survived pushes per impulse '
                                   'band and in the ambiguous band (20-80 %% fell); with --baselines also the Pareto fronts of '
                                   'the hand-coded baselines; with --per-run, each run\'s alarms. Samples '
                                   'the estimator or the feature extractor refuses are holes, as onboard, '
                                   'and counted (refused_samples). Not cross-validated: use a dataset the '
                                   'model was not trained on. Exit code 2 if the model or dataset cannot be '
                                   'used.')
    p.add_argument('--data', type=Path, required=True, help='dataset directory')
    p.add_argument('--model', type=Path, required=True, help='model file (JSON)')
    p.add_argument('--tau-his', type=argtypes.nonnegative, default=None,
                   help='history window [s] (default: the model\'s recommended value)')
    p.add_argument('--decision-threshold', type=argtypes.finite(float), default=None, metavar='LOG_ODDS',
                   help='boosted-trees models: falling when the score exceeds this (default: the '
                        'model\'s); the other half of their operating point beside --tau-his')
    p.add_argument('--band-width', type=argtypes.positive, default=10.0, metavar='NS',
                   help='impulse band width [N s] of the per-band FPR of survived pushes (default 10)')
    p.add_argument('--baselines', action='store_true',
                   help='also evaluate the CoM-height, momentum and capture-point baselines')
    p.add_argument('--per-run', type=Path, default=None, metavar='FILE',
                   help='also write one row per run: trajectory id, fallen, push time, fall time, first '
                        'alarm, lead or false alarm, alarm onsets before the push, refused samples '
                        '(CSV; JSON when FILE ends in .json)')
    argtypes.add_state_argument(p)
    p.add_argument('--jobs', type=argtypes.positive_int, default=1)
    p.add_argument('--skip-unreadable', action='store_true',
                   help='leave out unreadable bags instead of failing')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser('fit-direction', help='add a learned fall direction to a model',
                       description='Fit the fall direction the monitor reports (method §8b) at a model\'s '
                                   'triggers on a development dataset: the momentum\'s direction turned by '
                                   'an angle that boosted trees predict from the state seen from the '
                                   'momentum, fitted on the falls and their mirror images; write the model '
                                   'with it. Its decisions are unchanged. Exit code 2 if the model or the '
                                   'dataset cannot be used (a dataset without the true CoM cannot).')
    p.add_argument('--data', type=Path, required=True, help='development dataset directory')
    p.add_argument('--model', type=Path, required=True, help='model file (JSON) whose triggers to use')
    p.add_argument('--out', type=Path, required=True, help='model file to write (JSON)')
    argtypes.add_state_argument(p)
    p.add_argument('--no-mirror', action='store_true', help='fit without the mirror images')
    p.add_argument('--jobs', type=argtypes.positive_int, default=1, help='processes loading features')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.set_defaults(func=cmd_fit_direction)

    p = sub.add_parser('fit-time-to-fall', help='add a time to fall fitted at a model\'s triggers',
                       description='Fit the time to fall the monitor reports (method §8d) on a '
                                   'development dataset: boosted trees over the 15 features on every '
                                   '10th sample from each of the model\'s triggers until fallen (what '
                                   'the monitor reports on), in place of the per-mode trees that '
                                   '`train` fits on every falling state; write the model with it. '
                                   'Its decisions are unchanged. Exit code 2 if the model or the '
                                   'dataset cannot be used.')
    p.add_argument('--data', type=Path, required=True, help='development dataset directory')
    p.add_argument('--model', type=Path, required=True, help='model file (JSON) whose triggers to use')
    p.add_argument('--out', type=Path, required=True, help='model file to write (JSON)')
    argtypes.add_state_argument(p)
    p.add_argument('--jobs', type=argtypes.positive_int, default=1, help='processes loading features')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.set_defaults(func=cmd_fit_time_to_fall)
