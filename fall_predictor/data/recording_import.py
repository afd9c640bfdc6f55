"""Datasets from recorder_node bags (:mod:`fall_predictor.ros.recorder_node`: the simulator's or
the live estimator's state on the measurement topic, with the push topic): each bag one run of one
push, its fall found with the recorded robot's fallen height (its profile's), indexed as generated
runs are (:mod:`fall_predictor.data.generation`)."""
from __future__ import annotations

import json
import os
import shutil
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Iterable

import numpy as np

from fall_predictor.data.bagio import BagError, read_trajectory
from fall_predictor.data.dataset import (FORMAT, DatasetError, IndexRow, trajectory_id,
                                         write_index_csv)
from fall_predictor.data.generation import simulated_robot
from fall_predictor.data.outcomes import height_drop_time
from fall_predictor.monitor.fileio import atomic_write_text
from fall_predictor.profiles.profile import DEFAULT_ROBOT, load_profile


@dataclass
class ImportReport:
    rows: list[IndexRow]
    rejected: dict[str, str]         #: bag path -> why it cannot be a training trajectory


def _recorded_row(bag: Path, tid: str, fallen_height_m: float) -> IndexRow:
    """The index row of a recorder_node bag (the simulator's or the live estimator's state on
    the measurement topic): fallen below ``fallen_height_m``, the recorded robot's profile's."""
    from fall_predictor.data.bagio import iter_messages
    from fall_predictor.data.outcomes import first_fallen_time
    from fall_predictor.contract.topics import CONTROLLER_MODE

    recorded = read_trajectory(bag)
    if not recorded.pushes or len(recorded.pushes) != 1:
        raise DatasetError(f'{bag}: {len(recorded.pushes or [])} pushes recorded; a training trajectory '
                           'holds exactly one (method §3)')
    modes = [m.msg.data for m in iter_messages(bag, [CONTROLLER_MODE.name])]
    if 'fall' in modes:
        raise DatasetError(f'{bag}: C_fall took over during the recording; hindsight labels need C_bal '
                           'throughout (record with `bringup --no-fall-trigger`)')
    ms = recorded.measurements
    t = np.array([m.t for m in ms])
    z = np.array([m.com[2] for m in ms])
    t_fallen = first_fallen_time(t, z, np.array([m.non_foot_contact for m in ms]), fallen_height_m)
    push = recorded.pushes[0]
    at_push = ms[int(np.searchsorted(t, push.t))]
    angle = np.degrees(np.arctan2(push.force[1], push.force[0]) - at_push.heading)
    return IndexRow(trajectory_id=tid, bag=f'bags/{tid}', force_n=float(np.hypot(*push.force[:2])),
                    angle_deg=float((angle + 180.0) % 360.0 - 180.0), height_m=float('nan'),
                    t_push=push.t, t_force_end=round(push.t + 0.1, 6), fallen=t_fallen is not None,
                    t_fallen=t_fallen, t_height_drop=None if t_fallen is None else height_drop_time(t, z, t_fallen),
                    t_reflex=None, t_start=float(t[0]), t_end=float(t[-1]), samples=len(ms))


def import_recordings(bags: Iterable[str | os.PathLike], out: str | os.PathLike,
                      robot: str = DEFAULT_ROBOT) -> ImportReport:
    """Make a dataset directory from live recordings (e.g. ``recorder_node`` bags) of robot
    ``robot`` (a profile's name or path: its fallen CoM height labels the falls, its name and
    mass go into the manifest), so that ``train``, ``evaluate`` and ``sweep`` can use them. Bags
    are copied; the push height above the CoM is not recorded and is NaN in the index. Bags that
    cannot serve as training trajectories are reported in ``rejected`` with the reason, not
    imported."""
    fallen_height_m = load_profile(robot).fallen_com_height_m
    out = Path(out)
    if out.exists():
        raise DatasetError(f'{out}: exists; import into a new directory')
    (out / 'bags').mkdir(parents=True)
    (out / 'index').mkdir()
    sources = [str(Path(b).resolve()) for b in bags]
    manifest = {'format': FORMAT, 'source': 'recordings', 'bags': sources,
                'robot': simulated_robot(robot)}
    atomic_write_text(out / 'dataset.json', json.dumps(manifest, indent=1))
    rows, rejected = [], {}
    for source in sources:
        tid = trajectory_id(len(rows))
        try:
            row = _recorded_row(Path(source), tid, fallen_height_m)
        except (DatasetError, BagError) as exc:
            rejected[source] = str(exc)
            continue
        shutil.copytree(source, out / 'bags' / tid, copy_function=shutil.copy2)
        atomic_write_text(out / 'index' / f'{tid}.json', json.dumps(asdict(row), sort_keys=True))
        rows.append(row)
    write_index_csv(out, rows)
    return ImportReport(rows, rejected)
