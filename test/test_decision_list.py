import math
import pickle
from pathlib import Path

import numpy as np
import pytest

from fall_predictor.monitor.decision_list import (Condition, DecisionList, PerModeDecisionLists, Rule,
                                          simplify_conditions)
from fall_predictor.monitor.boosted_trees import BoostedTrees
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.records import BALANCED, CONTACT_MODE_NAMES, FALLING, FEATURE_NAMES, N_CONTACT_MODES

COM_Z = FEATURE_NAMES.index('com_z')
LIN_MOM_X = FEATURE_NAMES.index('lin_mom_x')
LIN_MOM_Y = FEATURE_NAMES.index('lin_mom_y')


def example_list() -> DecisionList:
    """if lin_mom_x > 10 and com_z <= 0.5 -> falling; elif lin_mom_y > 5 -> balanced;
    elif lin_mom_y > 0 -> falling; else balanced."""
    return DecisionList((
        Rule((Condition(LIN_MOM_X, '>', 10.0), Condition(COM_Z, '<=', 0.5)), FALLING),
        Rule((Condition(LIN_MOM_Y, '>', 5.0),), BALANCED),
        Rule((Condition(LIN_MOM_Y, '>', 0.0),), FALLING),
    ))


def vector(**values: float) -> list[float]:
    x = [0.0] * len(FEATURE_NAMES)
    x[COM_Z] = 0.59
    for name, value in values.items():
        x[FEATURE_NAMES.index(name)] = value
    return x


def test_first_matching_rule_wins():
    dl = example_list()
    assert dl.predict_one(vector(lin_mom_x=11.0, com_z=0.4, lin_mom_y=6.0)) == FALLING   # rule 1
    assert dl.predict_one(vector(lin_mom_x=11.0, com_z=0.6, lin_mom_y=6.0)) == BALANCED  # rule 2
    assert dl.predict_one(vector(lin_mom_y=3.0)) == FALLING                              # rule 3
    assert dl.predict_one(vector(lin_mom_y=-1.0)) == BALANCED                            # default
    # Boundaries: '<=' includes the threshold, '>' excludes it.
    assert dl.predict_one(vector(lin_mom_x=11.0, com_z=0.5, lin_mom_y=-1.0)) == FALLING
    assert dl.predict_one(vector(lin_mom_x=10.0, com_z=0.4, lin_mom_y=-1.0)) == BALANCED


def test_vectorised_predict_equals_predict_one_including_nan():
    rng = np.random.default_rng(1)
    X = rng.normal(scale=8.0, size=(2000, len(FEATURE_NAMES)))
    X[:, COM_Z] = rng.uniform(0.3, 0.7, 2000)
    X[rng.random(X.shape) < 0.05] = np.nan
    dl = example_list()
    expected = [dl.predict_one(row) for row in X.tolist()]
    assert dl.predict(X).tolist() == expected
    assert {BALANCED, FALLING} <= set(expected)
    # A NaN satisfies no comparison: NaN lin_mom_y cannot reach rule 3.
    assert dl.predict_one(vector(lin_mom_y=math.nan)) == BALANCED


def test_rule_size_and_depth():
    dl = example_list()
    assert dl.rule_size == 4
    assert dl.depth == 3
    assert DecisionList().rule_size == 0 and DecisionList().depth == 0


def test_format_matches_figure_8_form():
    dl = DecisionList((
        Rule((Condition(LIN_MOM_Y, '>', -64.5), Condition(COM_Z, '<=', 0.35)), FALLING),
        Rule((Condition(COM_Z, '>', 0.62),), FALLING),
    ))
    assert dl.format(mode_name='L-LEFT') == (
        'if footContactMode = L-LEFT then\n'
        '  if lin_mom_y > -64.5 and com_z <= 0.35 then\n'
        '    class <- falling.\n'
        '  else if com_z > 0.62 then\n'
        '    class <- falling.\n'
        '  else\n'
        '    class <- balanced.')
    assert DecisionList().format(mode_name='OUTSIDE') == (
        'if footContactMode = OUTSIDE then\n  class <- balanced.')
    hyphenated = [name.replace('_', '-') for name in FEATURE_NAMES]
    assert 'd-lin-mom-y' in DecisionList((Rule((Condition(10, '<=', 1.0),), FALLING),)).format(hyphenated)


@pytest.mark.parametrize('feature, op, threshold', [
    (15, '<=', 0.0), (-1, '<=', 0.0), (0, '>=', 0.0), (0, '<', 0.0),
    (0, '<=', math.nan), (0, '>', math.inf),
])
def test_condition_rejects_invalid_values(feature, op, threshold):
    with pytest.raises(ValueError):
        Condition(feature, op, threshold)


def test_rule_and_list_reject_fallen_label():
    with pytest.raises(ValueError):
        Rule((), 2)
    with pytest.raises(ValueError):
        DecisionList((), default=2)


def test_simplify_merges_same_feature_and_direction():
    merged = simplify_conditions([
        Condition(3, '>', 1.0), Condition(2, '<=', 0.5), Condition(3, '>', 2.0),
        Condition(2, '<=', 0.4), Condition(3, '<=', 9.0)])
    assert merged == (Condition(3, '>', 2.0), Condition(2, '<=', 0.4), Condition(3, '<=', 9.0))


def test_per_mode_lists_route_by_mode_and_mean_rule_size_counts_empty_modes():
    lists = [DecisionList() for _ in range(N_CONTACT_MODES)]
    l_left = CONTACT_MODE_NAMES.index('L-LEFT')
    lists[l_left] = example_list()
    per_mode = PerModeDecisionLists(tuple(lists))
    x = vector(lin_mom_y=3.0)
    assert per_mode.predict_one(x, l_left) == FALLING
    assert per_mode.predict_one(x, 0) == BALANCED
    assert per_mode.mean_rule_size == pytest.approx(4 / 16)
    assert per_mode.depths[l_left] == 3
    X = np.array([x, x, x])
    assert per_mode.predict(X, np.array([l_left, 0, l_left])).tolist() == [FALLING, BALANCED, FALLING]
    with pytest.raises(ValueError):
        per_mode.predict_one(x, 16)
    with pytest.raises(ValueError):
        per_mode.predict(X, np.array([0, -1, 0]))
    with pytest.raises(ValueError):
        PerModeDecisionLists(tuple(lists[:15]))
    assert PerModeDecisionLists.empty().mean_rule_size == 0.0


def _comparisons(classifier) -> list[tuple[int, float]]:
    """Every comparison a mode's classifier makes, as (input index, threshold): a list's
    conditions, or the trees' splits (over 19 inputs for a model reading the attitude)."""
    if isinstance(classifier, BoostedTrees):
        return [(f, tree.threshold[i]) for tree in classifier.trees
                for i, f in enumerate(tree.feature) if f != -1]
    return [(c.feature, c.threshold) for rule in classifier.rules for c in rule.conditions]


REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize('name', sorted(
    [p.name for p in (REPO / 'models').glob('*.json') if not p.name.endswith('.evaluation.json')]
    + ['../docs/prediction/asimo_like/plain_lists/plain_model.json']))
def test_shipped_lists_compiled_predict_one_equals_predict_at_and_around_every_threshold(name):
    """``predict_one`` runs the rules (or trees) as generated Python code: it must compare exactly as the
    vectorised path, at each threshold itself (a threshold written back wrongly by one ulp flips
    it), one ulp either side, and with NaN; a pickled list (a sweep's worker result) too."""
    lists, _ = load_model(Path(__file__).resolve().parents[1] / 'models' / name)
    rng = np.random.default_rng(7)
    checked = 0
    for dl in lists.lists:
        conditions = _comparisons(dl)
        if not conditions:
            continue
        X = rng.normal(scale=2.0, size=(600, lists.n_inputs))     # (the attitude's model: 19)
        # Every row sits exactly on (or next to) the thresholds of a few conditions.
        for row in X:
            for k in rng.choice(len(conditions), size=4):
                feature, threshold = conditions[k]
                row[feature] = np.nextafter(threshold, rng.choice([-np.inf, np.inf])) \
                    if rng.random() < 0.5 else threshold
        X[rng.random(X.shape) < 0.03] = np.nan
        expected = dl.predict(X).tolist()
        assert [dl.predict_one(row) for row in X.tolist()] == expected
        again = pickle.loads(pickle.dumps(dl))
        assert again == dl and [again.predict_one(row) for row in X.tolist()] == expected
        checked += 1
    assert checked >= 8
