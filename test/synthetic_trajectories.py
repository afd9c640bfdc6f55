"""Synthetic trajectories with a known falling rule, shared by the learning/metrics tests.

Every trajectory lasts ``duration_s`` at 1 kHz with features drawn from N(0, 1), except the
CoM height (0.59 m +- 5 mm). Before the push the contact mode is LR-INSIDE; from the push on
it is L-LEFT. On a fallen trajectory ``lin_mom_y`` lies in [5, 8] from ``t_height_drop`` to
``t_fallen`` and the CoM lies at 0.30 m from ``t_fallen`` on. So, in mode L-LEFT, falling
training samples (tau_plus = 0) are separated from balanced ones by ``lin_mom_y > ~4.5``
and nothing else; a predictor with that rule has lead ``t_fallen - t_height_drop``.
"""
from __future__ import annotations

import numpy as np

from fall_predictor.monitor.records import CONTACT_MODE_NAMES, FEATURE_NAMES, TrajectoryFeatures

DT_S = 0.001
T_PUSH_S = 0.5
T_HEIGHT_DROP_S = 1.0
T_FALLEN_S = 1.5
FALLING_MODE = CONTACT_MODE_NAMES.index('L-LEFT')
PRE_PUSH_MODE = CONTACT_MODE_NAMES.index('LR-INSIDE')
LIN_MOM_Y = FEATURE_NAMES.index('lin_mom_y')
COM_Z = FEATURE_NAMES.index('com_z')


def make_trajectory(trajectory_id: str, fallen: bool, rng: np.random.Generator,
                    duration_s: float = 2.0) -> TrajectoryFeatures:
    n = int(round(duration_s / DT_S))
    t = np.arange(n) * DT_S
    X = rng.normal(size=(n, len(FEATURE_NAMES)))
    X[:, COM_Z] = 0.59 + 0.005 * rng.uniform(-1.0, 1.0, n)
    mode = np.where(t < T_PUSH_S, PRE_PUSH_MODE, FALLING_MODE)
    if fallen:
        dropping = (t >= T_HEIGHT_DROP_S) & (t < T_FALLEN_S)
        X[dropping, LIN_MOM_Y] = rng.uniform(5.0, 8.0, int(dropping.sum()))
        X[t >= T_FALLEN_S, COM_Z] = 0.30
    return TrajectoryFeatures(
        trajectory_id=trajectory_id, t=t, X=X, mode=mode, fallen=fallen,
        t_push=T_PUSH_S, t_force_end=T_PUSH_S + 0.1,
        t_fallen=T_FALLEN_S if fallen else None,
        t_height_drop=T_HEIGHT_DROP_S if fallen else None)


def make_dataset(n_fallen: int, n_balanced: int, seed: int,
                 duration_s: float = 2.0) -> list[TrajectoryFeatures]:
    rng = np.random.default_rng(seed)
    return ([make_trajectory(f'fallen-{i}', True, rng, duration_s) for i in range(n_fallen)]
            + [make_trajectory(f'balanced-{i}', False, rng, duration_s) for i in range(n_balanced)])
