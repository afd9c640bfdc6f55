"""The held-out test dataset of a sweep (method §11): the sweep's chosen predictors evaluated on
a dataset drawn with another seed that took no part in any choice.

Which predictors: each nested operating point's setting as chosen on *all* folds of the sweep
dataset (legitimate here: the test set played no part in it), and the paper's own settings that
are in the grid. Each distinct ``tau_plus`` is trained once on every trajectory of the sweep
dataset, with the sweep's learner and sample stride; the test figures carry the same intervals
and the lists-alone figures as any evaluation. The CoM guard is the sweep's (its dataset's robot's),
the guard those predictors, trained on it, would record and run with.
"""
from __future__ import annotations

from typing import Any, Optional

from fall_predictor.learning.evaluation import evaluation_result_json
from fall_predictor.learning.metrics import evaluate_lists
from fall_predictor.learning.sweep_results import SweepResult
from fall_predictor.learning.training import PathLike, fit_strided, load_dataset, make_learner


def chosen_settings(nested_document: Optional[dict[str, Any]]) -> dict[str, tuple[float, float]]:
    """``{name: (tau_plus_s, tau_his_s)}`` of the predictors a sweep chose or fixed in advance."""
    if nested_document is None:
        return {}
    settings = {f"best lead at FPR <= {entry['max_fpr']}": tuple(entry['selected_in_hindsight'])
                for entry in nested_document['nested']}
    settings.update({f'{name} settings (fixed)': tuple(entry['setting'])
                     for name, entry in nested_document['paper_settings_fixed'].items()
                     if entry.get('in_grid') is not False})
    return settings


def evaluate_on_test_set(result: SweepResult, nested_document: Optional[dict[str, Any]],
                         test_dir: PathLike, jobs: int = 1, skip_unreadable: bool = False,
                         progress: bool = False) -> dict[str, Any]:
    """Train the chosen predictors on the whole sweep dataset; evaluate them on ``test_dir``.

    Raises :class:`~fall_predictor.data.dataset.DatasetError` if the test dataset is unusable or
    is the sweep dataset itself (same fingerprint).
    """
    from fall_predictor.data.dataset import DatasetError, dataset_guard_com_height_m

    test = load_dataset(test_dir, jobs, skip_unreadable, progress, result.config.state)
    if test.fingerprint == result.dataset_fingerprint:
        raise DatasetError(f'{test_dir}: the test dataset is the sweep dataset itself')
    train = load_dataset(result.data_dir, jobs, skip_unreadable, progress, result.config.state)
    config = result.config
    guard = (dataset_guard_com_height_m(result.data_dir) if config.guard_com_height_m is None
             else config.guard_com_height_m)
    learner = make_learner(config.learner_name, config.learner_params)
    settings = chosen_settings(nested_document)
    models = {tau_plus: fit_strided(train.trajectories, tau_plus, learner, config.sample_stride,
                                    mirror=config.mirror)
              for tau_plus in sorted({s[0] for s in settings.values()})}
    predictors = []
    for name, (tau_plus, tau_his) in settings.items():
        evaluation = evaluate_lists(test.trajectories, models[tau_plus], (tau_his,),
                                    guard_com_height_m=guard)[float(tau_his)]
        predictors.append({'name': name, 'tau_plus_s': tau_plus, 'tau_his_s': tau_his,
                           **evaluation_result_json(evaluation)})
    return {'format': 'fall_predictor/test-set/v1', 'test_data': str(test_dir),
            'test_fingerprint': test.fingerprint, 'train_data': result.data_dir,
            'train_fingerprint': result.dataset_fingerprint,
            'state': {'train': train.state, 'test': test.state}, 'guard_com_height_m': guard,
            'n_test_trajectories': len(test.trajectories),
            'n_test_fallen': sum(t.fallen for t in test.trajectories),
            'unreadable': dict(test.errors), 'predictors': predictors}
