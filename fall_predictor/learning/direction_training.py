"""Learning the fall direction (method §8b): the momentum's direction turned by a learned angle.

At a model's trigger the horizontal momentum points within ~17° (median) of where the CoM then
goes until the robot is down; the rest of the state says part of the remaining turn. A
:class:`~fall_predictor.monitor.fall_direction.LearnedDirection` predicts that turn from
:func:`~fall_predictor.monitor.fall_direction.direction_inputs` (the state seen from the
momentum) with scikit-learn's histogram gradient boosting under the absolute error (the median
turn, robust to the few falls that change course), exported to plain-data trees.

It is fitted where it is used: at the triggers of the model it will ride with, on the
development data, with each fall's left-right mirror image (the turn flips sign with the
reflection, so the trees learn an odd function of the sideways inputs); the actual direction is
the true CoM's displacement from the trigger to fallen
(:func:`~fall_predictor.learning.when_where.actual_directions`).
"""
from __future__ import annotations

import math
from typing import Optional, Sequence

import numpy as np

from fall_predictor.learning.boosting import exported_trees
from fall_predictor.learning.mirror import MIRROR_SIGNS
from fall_predictor.learning.when_where import (DirectionSamples, direction_samples,
                                                trigger_indices)
from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.monitor.fall_direction import (DIRECTION_INPUT_NAMES, LearnedDirection,
                                                   direction_inputs)
from fall_predictor.monitor.records import TrajectoryFeatures

#: The learner's settings: chosen by 5-fold cross-validation on the ASIMO-like robot's
#: development set at the shipped model's triggers (docs/results.md), within 0.7° of each other
#: over 100-200 trees, learning rate 0.03-0.1, depth 2-3 and 20-40 samples a leaf.
DIRECTION_LEARNER_PARAMS = {'max_iter': 100, 'learning_rate': 0.05, 'max_depth': 3,
                            'min_samples_leaf': 20, 'loss': 'absolute_error'}


def trigger_samples(data_dir, trajectories: Sequence[TrajectoryFeatures],
                    lists: PerModeDecisionLists, tau_his_s: float,
                    guard_com_height_m: float) -> DirectionSamples:
    """The features and actual fall directions at ``lists``' in-time triggers on ``data_dir``
    (its true CoM: a simulated dataset)."""
    return direction_samples(data_dir, trajectories, trigger_indices(
        trajectories, lists, tau_his_s, guard_com_height_m))


def turn_targets(samples: DirectionSamples) -> tuple[np.ndarray, np.ndarray]:
    """The direction inputs (N', 8) and the turn [rad] in (-pi, pi] from each sample's momentum
    direction to its actual direction (N',), for the samples whose momentum has a direction."""
    inputs, turns = [], []
    for x, (ax, ay) in zip(samples.X, samples.actual):
        values = direction_inputs(x.tolist())
        if values is None:
            continue
        turn = math.atan2(ay, ax) - math.atan2(values[1], values[0])
        inputs.append(values)
        turns.append((turn + math.pi) % (2.0 * math.pi) - math.pi)
    return (np.array(inputs, dtype=float).reshape(len(inputs), len(DIRECTION_INPUT_NAMES)),
            np.array(turns, dtype=float))


def mirrored(samples: DirectionSamples) -> DirectionSamples:
    """The samples' left-right mirror images (:mod:`fall_predictor.learning.mirror`)."""
    return DirectionSamples(samples.X * MIRROR_SIGNS, samples.actual * np.array([1.0, -1.0]))


def fit_learned_direction(samples: DirectionSamples, mirror: bool = True, random_state: int = 0,
                          params: Optional[dict] = None,
                          ignore_inputs: Sequence[str] = ()) -> LearnedDirection:
    """Boosted trees predicting the turn from the momentum's direction to the actual one
    (:data:`DIRECTION_LEARNER_PARAMS` updated with ``params``), on ``samples`` and, with
    ``mirror``, their mirror images; ``ignore_inputs``: names of inputs the trees may not use
    (held constant while fitting: what the others know without them). ValueError for fewer than
    20 usable samples or an unknown input name."""
    from sklearn.ensemble import HistGradientBoostingRegressor
    if mirror:
        samples = DirectionSamples(np.vstack([samples.X, mirrored(samples).X]),
                                   np.vstack([samples.actual, mirrored(samples).actual]))
    inputs, turns = turn_targets(samples)
    for name in ignore_inputs:
        if name not in DIRECTION_INPUT_NAMES:
            raise ValueError(f'{name!r} is not a direction input: {DIRECTION_INPUT_NAMES}')
        inputs[:, DIRECTION_INPUT_NAMES.index(name)] = 0.0      # a constant is never split on
    if turns.size < 20:
        raise ValueError(f'{turns.size} falls with a momentum direction: too few to learn a '
                         'fall direction from (at least 20)')
    model = HistGradientBoostingRegressor(**{**DIRECTION_LEARNER_PARAMS, **(params or {})},
                                          early_stopping=False, random_state=random_state)
    model.fit(inputs, turns)
    bias, trees = exported_trees(model, len(DIRECTION_INPUT_NAMES))
    return LearnedDirection(trees, bias)
