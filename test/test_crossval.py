"""The cross-validation (fall_predictor.learning.crossval): folds by trajectory, the (fold,
tau_plus) trainings and their aggregation, on synthetic trajectories with a known rule."""
import numpy as np
import pytest

from fall_predictor.learning import crossval
from fall_predictor.learning.crossval import (aggregate_folds, cross_validate_grid,
                                              cross_validated_evaluation,
                                              stratified_trajectory_folds)
from fall_predictor.learning.learners import CoveringListLearner, TreeListLearner
from fall_predictor.learning.training import make_learner

from synthetic_trajectories import T_FALLEN_S, T_HEIGHT_DROP_S, T_PUSH_S, make_dataset


def test_folds_are_stratified_and_never_split_a_trajectory():
    trajectories = make_dataset(n_fallen=13, n_balanced=17, seed=0, duration_s=0.01)
    folds = stratified_trajectory_folds(trajectories, folds=4, seed=0)
    assert sorted(np.concatenate(folds).tolist()) == list(range(30))
    assert sorted(len(f) for f in folds) == [7, 7, 8, 8]
    fallen_counts = [sum(trajectories[i].fallen for i in fold) for fold in folds]
    assert max(fallen_counts) - min(fallen_counts) <= 1
    assert [f.tolist() for f in folds] == [f.tolist() for f in stratified_trajectory_folds(trajectories, 4, 0)]
    assert [f.tolist() for f in folds] != [f.tolist() for f in stratified_trajectory_folds(trajectories, 4, 1)]
    with pytest.raises(ValueError):
        stratified_trajectory_folds(trajectories, folds=1, seed=0)


@pytest.mark.parametrize('learner', [TreeListLearner(), CoveringListLearner()],
                         ids=lambda learner: type(learner).__name__)
def test_cross_validation_on_synthetic_data(learner, monkeypatch):
    """Separable synthetic data: every fold learns ``lin_mom_y > ~4.5``, so FPR 0 and lead
    ``t_fallen - t_height_drop - tau_his``; each trajectory is tested once, by a model that
    never saw any of its samples."""
    trajectories = make_dataset(n_fallen=8, n_balanced=8, seed=31, duration_s=1.6)
    all_ids = {traj.trajectory_id for traj in trajectories}
    trained_on, tested_on = [], []

    def recording_fit(train, *args, **kwargs):
        trained_on.append({traj.trajectory_id for traj in train})
        return fit_strided(train, *args, **kwargs)

    def recording_evaluation(test, *args, **kwargs):
        tested_on.append([traj.trajectory_id for traj in test])
        return evaluate_atomic(test, *args, **kwargs)

    fit_strided, evaluate_atomic = crossval.fit_strided, crossval.evaluate_atomic
    monkeypatch.setattr(crossval, 'fit_strided', recording_fit)
    monkeypatch.setattr(crossval, 'evaluate_atomic', recording_evaluation)
    fits = cross_validate_grid(trajectories, learner, (0.0,), (0.0, 0.01), folds=4, seed=0,
                               sample_stride=1)

    assert [fit.fold for fit in fits] == [0, 1, 2, 3] and len(trained_on) == len(tested_on) == 4
    for fit, train, test in zip(fits, trained_on, tested_on):
        assert train.isdisjoint(test) and train | set(test) == all_ids    # never split
        assert fit.n_train == len(train) == 12
        assert fit.results[0.0].n_trajectories == len(test) == 4
        assert fit.results[0.0].n_fallen == sum(i.startswith('fallen') for i in test) == 2
    assert sorted(i for test in tested_on for i in test) == sorted(all_ids)  # each tested once

    lead = T_FALLEN_S - T_HEIGHT_DROP_S
    for tau_his in (0.0, 0.01):
        point = aggregate_folds(fits, tau_his)
        assert point.n_balanced == 8 and point.n_fallen == 8 and point.n_missed == 0
        assert point.tau_lead_s == pytest.approx(lead - tau_his)            # 0.49 s at 10 ms
        assert point.tau_lead_std_s == pytest.approx(0.0, abs=1e-9)
        assert point.oracle_lead_s == pytest.approx(T_FALLEN_S - T_PUSH_S)
        assert point.mean_rule_size == pytest.approx(1 / 16)               # one comparison
        assert [r.n_trajectories for r in point.per_fold] == [4, 4, 4, 4]
    # Without a window a lone noise sample beyond the learned threshold may raise an alarm on
    # a balanced trajectory; a 10 ms window suppresses it.
    point = aggregate_folds(fits, 0.01)
    assert point.fpr == 0.0 and point.fpr_std == 0.0 and point.n_false_positives == 0
    assert point.n_pre_push_alarms == 0


def test_cross_validated_evaluation_has_the_known_fpr_and_lead():
    trajectories = make_dataset(6, 6, seed=4)
    points = cross_validated_evaluation(trajectories, make_learner('tree'), 0.0, (0.003, 0.05),
                                        folds=3, seed=0, sample_stride=10)
    lead = T_FALLEN_S - T_HEIGHT_DROP_S
    for point, tau_his in zip(points, (0.003, 0.05)):
        assert point.tau_his_s == tau_his and point.tau_plus_s == 0.0
        assert point.fpr == 0.0 and point.n_false_positives == 0 and point.n_balanced == 6
        assert point.n_missed == 0 and point.n_fallen == 6
        assert point.tau_lead_s == pytest.approx(lead - tau_his, abs=0.02)
        assert point.oracle_lead_s == pytest.approx(T_FALLEN_S - 0.5)
        assert point.n_train == 8.0 and len(point.per_fold) == 3
        assert point.mean_rule_size > 0


def test_cross_validation_in_parallel_processes_matches_one_process():
    trajectories = make_dataset(4, 4, seed=5)
    kwargs = dict(tau_plus_values=(-0.5, 0.0), tau_his_values=(0.0, 0.01), folds=2, seed=1,
                  sample_stride=20, train_sizes=(None, 3))
    serial = cross_validate_grid(trajectories, make_learner('tree'), jobs=1, **kwargs)
    parallel = cross_validate_grid(trajectories, make_learner('tree'), jobs=2, **kwargs)
    assert len(serial) == 2 * 2 * 2
    assert [(f.fold, f.tau_plus_s, f.train_size, f.n_train, f.rule_sizes, f.results)
            for f in serial] == [(f.fold, f.tau_plus_s, f.train_size, f.n_train, f.rule_sizes,
                                  f.results) for f in parallel]
    assert {f.n_train for f in serial if f.train_size == 3} == {3}


def test_aggregate_folds_means_rates_and_sums_counts():
    trajectories = make_dataset(4, 4, seed=6)
    fits = cross_validate_grid(trajectories, make_learner('tree'), (0.0,), (0.0,), folds=2,
                               sample_stride=20)
    point = aggregate_folds(fits, 0.0)
    assert point.n_fallen == 4 and point.n_balanced == 4
    assert point.fpr == pytest.approx(np.mean([f.results[0.0].fpr for f in fits]))
    assert point.mean_rule_size == pytest.approx(np.mean([f.mean_rule_size for f in fits]))
    with pytest.raises(ValueError, match='one tau_plus'):
        aggregate_folds(fits + cross_validate_grid(trajectories, make_learner('tree'), (0.3,),
                                                   (0.0,), folds=2, sample_stride=20), 0.0)


def test_the_test_folds_run_with_the_given_guard():
    """The synthetic CoM stands at 0.59 +- 0.005 m: a guard at 0.60 m fires from the first sample
    (every balanced trajectory a false alarm, every fall predicted at the push by the guard
    alone); the default guard only once the robot lies at 0.30 m, at t_fallen (no lead)."""
    trajectories = make_dataset(n_fallen=4, n_balanced=4, seed=5, duration_s=2.0)
    high = cross_validated_evaluation(trajectories, make_learner('tree'), 0.0, (0.0,), folds=2,
                                      seed=0, guard_com_height_m=0.60)[0]
    assert high.fpr == 1.0 and high.n_missed == 0
    assert [r.tau_lead_guard_only_s for r in high.per_fold] == \
        pytest.approx([T_FALLEN_S - T_PUSH_S] * 2, abs=1e-9)
    default = cross_validated_evaluation(trajectories, make_learner('tree'), 0.0, (0.0,), folds=2,
                                         seed=0)[0]
    assert [r.tau_lead_guard_only_s for r in default.per_fold] == [0.0, 0.0]


def test_mirror_trains_each_fold_on_its_trajectories_and_their_mirror_images():
    """The CV with mirror equals, fold by fold, a training on the fold's training trajectories
    plus their mirror images (fit_strided(mirror=True)) evaluated on the recorded test fold."""
    from fall_predictor.learning.evaluation import evaluate_lists
    from fall_predictor.learning.mirror import with_mirror_images
    from fall_predictor.learning.training import fit_strided

    trajectories = make_dataset(4, 4, seed=7)
    learner = make_learner('tree')
    fits = cross_validate_grid(trajectories, learner, (0.0,), (0.0, 0.02), folds=2, seed=3,
                               sample_stride=20, mirror=True)
    for fit, test_index in zip(fits, stratified_trajectory_folds(trajectories, 2, 3)):
        train = [t for i, t in enumerate(trajectories) if i not in set(test_index.tolist())]
        assert fit.n_train == len(train)             # counted as recorded trajectories
        lists = fit_strided(with_mirror_images(train), 0.0, learner, 20)
        expected = evaluate_lists([trajectories[i] for i in test_index], lists, (0.0, 0.02))
        assert fit.rule_sizes == lists.rule_sizes
        for tau_his in (0.0, 0.02):
            assert fit.results[tau_his].n_false_positives == expected[tau_his].n_false_positives
            assert fit.results[tau_his].tau_lead_s == pytest.approx(expected[tau_his].tau_lead_s)


def test_grouped_folds_never_split_a_group_between_training_and_test():
    from fall_predictor.learning.crossval import grouped_trajectory_folds
    rng = np.random.default_rng(4)
    groups = [('push', int(k)) for k in rng.integers(0, 7, 60)] + [('trip',)] * 9 + [('walk',)] * 3
    for folds in (2, 5, 10):
        test_folds = grouped_trajectory_folds(groups, folds, seed=1)
        assert len(test_folds) == min(folds, 9)
        assert sorted(np.concatenate(test_folds).tolist()) == list(range(len(groups)))
        for test in test_folds:
            inside = {groups[i] for i in test}
            outside = {groups[i] for i in set(range(len(groups))) - set(test.tolist())}
            assert not inside & outside
    sizes = [f.size for f in grouped_trajectory_folds([(i // 4,) for i in range(40)], 5, seed=0)]
    assert sizes == [8] * 5                                  # ten groups of 4 dealt evenly
    with pytest.raises(ValueError, match='2 groups'):
        grouped_trajectory_folds([('push', 0)] * 5, 3, seed=0)


def test_cross_validation_with_groups_tests_each_group_on_a_model_that_never_saw_it():
    trajectories = make_dataset(n_fallen=6, n_balanced=6, seed=2)
    groups = [('a',)] * 4 + [('b',)] * 4 + [('c',)] * 4
    fits = cross_validate_grid(trajectories, make_learner('tree'), (0.0,), (0.0,), folds=5,
                               groups=groups)
    assert len(fits) == 3 and all(fit.n_train == 8 for fit in fits)
