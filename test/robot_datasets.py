"""A tiny hand-made dataset of a chosen robot whose CoM sinks between the ASIMO-like robot's CoM
guard (0.48 m) and the G1's (0.55 m), so that the guard alone decides the outcome of every
evaluation (no simulation: the bags are written from known measurements).

Both feet stand flat on the ground throughout (contact mode LR-INSIDE), with zero momenta, for
0.5 s at 1 kHz; the push is at 0.1 s. The CoM stands at 0.60 m and moves at 1 m/s:

* a **fallen** trajectory sinks from 0.20 s on (0.55 m at 0.25 s, 0.50 m at ``t_fallen`` =
  0.30 s, 0.48 m at 0.32 s): the G1's guard predicts it :data:`G1_GUARD_LEAD_S` ahead, the
  ASIMO-like robot's only after ``t_fallen`` (a miss);
* a **balanced** trajectory squats from 0.20 s to 0.52 m at 0.28 s and stands up again by
  0.36 s: a false alarm of the G1's guard, none of the ASIMO-like robot's.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from fall_predictor.data.bag_writer import BagWriter
from fall_predictor.data.dataset import FORMAT, IndexRow, trajectory_id, write_index_csv
from fall_predictor.monitor.records import Measurement
from fall_predictor.profiles.profile import load_profile

DT_S = 0.001
DURATION_S = 0.5
T_PUSH_S = 0.1
T_SINK_S = 0.2
T_FALLEN_S = 0.3
STANDING_COM_M = 0.60
SQUAT_COM_M = 0.52
#: The G1's guard (0.55 m) fires at the first sample below it: 0.251 s, 0.049 s before t_fallen.
G1_GUARD_LEAD_S = 0.049


def com_height_m(t: float, fallen: bool) -> float:
    """The CoM height [m] at time ``t`` [s] of either trajectory (module docs)."""
    sunk = max(0.0, t - T_SINK_S)                       # 1 m/s
    if fallen:
        return STANDING_COM_M - sunk
    return max(SQUAT_COM_M, STANDING_COM_M - sunk, STANDING_COM_M - (0.36 - min(t, 0.36)))


def _feet(y: float) -> np.ndarray:
    """Four contact points (x, y, normal force) of a flat sole centred at (0, y)."""
    return np.array([[x, y + dy, 100.0] for x in (-0.08, 0.08) for dy in (-0.03, 0.03)])


def measurements(fallen: bool) -> list[Measurement]:
    out = []
    for k in range(int(round(DURATION_S / DT_S))):
        t = round(k * DT_S, 6)
        out.append(Measurement(
            t=t, com=np.array([0.0, 0.0, com_height_m(t, fallen)]), lin_mom=np.zeros(3),
            ang_mom=np.zeros(3), heading=0.0, cop=np.zeros(3), left_contacts=_feet(0.1),
            right_contacts=_feet(-0.1), left_foot=np.array([0.0, 0.1, 0.0]),
            right_foot=np.array([0.0, -0.1, 0.0]), non_foot_contact=False))
    return out


def write_robot_dataset(out: Path, robot: str = 'g1', n_fallen: int = 2, n_balanced: int = 2
                        ) -> Path:
    """Write the dataset (``n_fallen`` then ``n_balanced`` trajectories) of ``robot`` to ``out``."""
    out = Path(out)
    profile = load_profile(robot)
    (out / 'index').mkdir(parents=True)
    (out / 'dataset.json').write_text(json.dumps({
        'format': FORMAT, 'robot': {'name': profile.name, 'profile': robot,
                                    'total_mass_kg': profile.total_mass_kg}}))
    rows = []
    for i, fallen in enumerate([True] * n_fallen + [False] * n_balanced):
        ms = measurements(fallen)
        row = IndexRow(trajectory_id(i), f'bags/{trajectory_id(i)}', 100.0, 90.0, 0.1, T_PUSH_S,
                       T_PUSH_S + 0.1, fallen, T_FALLEN_S if fallen else None,
                       T_SINK_S if fallen else None, None, 0.0, ms[-1].t, len(ms))
        (out / 'bags').mkdir(exist_ok=True)
        with BagWriter(out / row.bag) as writer:
            for m in ms:
                writer.write_measurement(m)
        (out / 'index' / f'{row.trajectory_id}.json').write_text(json.dumps(dataclasses.asdict(row)))
        rows.append(row)
    write_index_csv(out, rows)
    return out
