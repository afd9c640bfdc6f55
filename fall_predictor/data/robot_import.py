"""Datasets from a real robot's recordings: ``ros2 bag record`` of its standard sensor topics.

A robot records ``/joint_states``, ``/imu/data``, ``/left_foot/wrench``, ``/right_foot/wrench``
and ``/robot_description`` (or the URDF is given); there is no push topic and no true state.
Each recording becomes one trajectory of a dataset whose features can only come from the
estimated state (``--state estimated``). Its labels come from the same estimator:

* **fallen** when the estimated CoM height drops below ``FALLEN_HEIGHT_FRACTION`` of its
  median over the recording's first ``STANDING_WINDOW_S`` (0.35 m of 0.59 m on the simulated
  robot: a little above the simulator's own 0.33 m rule, so that the estimate's error cannot
  miss a fall in a recording that ends as the robot lands), or the torso's fused tilt from the
  IMU exceeds ``FALLEN_TILT_DEG``; ``t_fallen`` is the first such sample and
  ``t_height_drop`` the start of the CoM's final descent, as for simulated data;
* the perturbation onset is unknown, so ``t_push`` is the recording's start: every alarm on a
  recording that does not fall is a false alarm, and the lead is measured from the recording's
  start. Training is unaffected (falling states are trained on from ``t_height_drop +
  tau_plus`` only).

A model belongs to the robot it was trained on: the features and the CoM guard are in metres
and kilograms of that robot, so another robot needs recordings (or a simulation) of its own.
"""
from __future__ import annotations

import json
import os
import shutil
from dataclasses import asdict
from pathlib import Path
from typing import Iterable, Optional

import numpy as np

from fall_predictor.profiles import DEFAULT_ROBOT
from fall_predictor.data.bagio import BagError
from fall_predictor.data.dataset import (FORMAT, ROBOT_URDF_FILE, DatasetError, IndexRow, trajectory_id,
                                         write_index_csv)
from fall_predictor.data.outcomes import height_drop_time
from fall_predictor.monitor.fileio import atomic_write_text

#: Fallen below this fraction of the standing CoM height (0.35 of 0.59 m on the simulated robot).
FALLEN_HEIGHT_FRACTION = 0.6
#: ... or with the torso tilted beyond this [deg] (fused roll or pitch).
FALLEN_TILT_DEG = 60.0
#: The standing CoM height is the median over this first part of a recording [s].
STANDING_WINDOW_S = 0.5


def robot_from_urdf(urdf: str) -> dict:
    """Name and total mass [kg] of the robot of a URDF (what a dataset records about it)."""
    import pinocchio

    try:
        model = pinocchio.buildModelFromXML(urdf, pinocchio.JointModelFreeFlyer())
    except (RuntimeError, ValueError) as error:
        raise DatasetError(f'the robot description is not a usable URDF: {error}') from error
    data = model.createData()
    pinocchio.computeTotalMass(model, data)
    return {'name': model.name, 'total_mass_kg': float(data.mass[0]), 'source': 'urdf'}


def robot_recording_row(bag: Path, tid: str, urdf: Optional[str] = None,
                        robot: str = DEFAULT_ROBOT) -> IndexRow:
    """The index row of one robot recording, labelled from the estimated state (module docs)."""
    from fall_predictor.data.estimation import estimated_measurements
    from fall_predictor.data.sensorbag import read_imu, read_robot_description
    from fall_predictor.monitor.geometry import fused_roll_pitch

    if urdf is None:
        urdf = read_robot_description(bag)
        if urdf is None:
            raise DatasetError(f'{bag}: no /robot_description in the recording; give the URDF (--urdf)')
    ms = estimated_measurements(bag, urdf=urdf, robot=robot)
    if len(ms) < 2:
        from fall_predictor.data.sensorbag import STREAM_TOPICS
        from fall_predictor.profiles import load_profile
        streams = ('joints', 'imu', *load_profile(robot).sensor_layout().force_sensors)
        needed = [STREAM_TOPICS[stream].name for stream in streams]
        raise DatasetError(f'{bag}: the estimator gave {len(ms)} states; the {robot} robot needs '
                           f'{", ".join(needed)}')
    t = np.array([m.t for m in ms])
    z = np.array([m.com[2] for m in ms])
    standing = float(np.median(z[t <= t[0] + STANDING_WINDOW_S]))
    t_imu, quat, _ = read_imu(bag)
    tilt = np.degrees(np.max(np.abs(fused_roll_pitch(quat)), axis=1))
    tilted = tilt[np.clip(np.searchsorted(t_imu, t), 0, len(t_imu) - 1)] > FALLEN_TILT_DEG
    fallen = (z < FALLEN_HEIGHT_FRACTION * standing) | tilted
    t_fallen = float(t[np.argmax(fallen)]) if fallen.any() else None
    t0 = float(t[0])
    nan = float('nan')
    return IndexRow(trajectory_id=tid, bag=f'bags/{tid}', force_n=nan, angle_deg=nan, height_m=nan,
                    t_push=t0, t_force_end=t0, fallen=t_fallen is not None, t_fallen=t_fallen,
                    t_height_drop=None if t_fallen is None else height_drop_time(t, z, t_fallen),
                    t_reflex=None, t_start=t0, t_end=float(t[-1]), samples=len(ms))


def import_robot_recordings(bags: Iterable[str | os.PathLike], out: str | os.PathLike,
                            urdf: Optional[str] = None,
                            robot: str = DEFAULT_ROBOT) -> tuple[list[IndexRow], dict[str, str]]:
    """A new dataset directory ``out`` from robot recordings (module docs) of the robot whose
    profile is ``robot`` (name or path); returns its rows and the recordings rejected, with the
    reason."""
    out = Path(out)
    if out.exists():
        raise DatasetError(f'{out}: exists; import into a new directory')
    sources = [Path(b).resolve() for b in bags]
    (out / 'bags').mkdir(parents=True)
    (out / 'index').mkdir()
    rows, rejected, described = [], {}, None
    for source in sources:
        tid = trajectory_id(len(rows))
        try:
            row = robot_recording_row(source, tid, urdf, robot)
            if described is None:
                from fall_predictor.data.sensorbag import read_robot_description
                described = robot_from_urdf(urdf or read_robot_description(source))
        except (DatasetError, BagError) as error:
            rejected[str(source)] = str(error)
            continue
        shutil.copytree(source, out / 'bags' / tid, copy_function=shutil.copy2)
        atomic_write_text(out / 'index' / f'{tid}.json', json.dumps(asdict(row), sort_keys=True))
        rows.append(row)
    manifest = {'format': FORMAT, 'source': 'robot_recordings', 'bags': [str(s) for s in sources],
                'robot': None if described is None else {**described, 'profile': str(robot)},
                'ground_truth': False, 'sensors': {'recorded_on': 'robot'},
                'fall_rule': {'height_fraction': FALLEN_HEIGHT_FRACTION, 'tilt_deg': FALLEN_TILT_DEG,
                              'standing_window_s': STANDING_WINDOW_S}}
    if urdf is not None:                 # recordings without /robot_description
        atomic_write_text(out / ROBOT_URDF_FILE, urdf)
        manifest['urdf_file'] = ROBOT_URDF_FILE
    atomic_write_text(out / 'dataset.json', json.dumps(manifest, indent=1))
    write_index_csv(out, rows)
    return rows, rejected


def is_robot_recording(bag: str | os.PathLike) -> bool:
    """Whether a bag is a robot's recording: an IMU topic and no simulator measurement topic."""
    from fall_predictor.data.bagio import iter_messages
    from fall_predictor.contract.topics import IMU, MEASUREMENT

    def has(topic: str) -> bool:
        return next(iter(iter_messages(Path(bag), (topic,))), None) is not None
    try:
        return has(IMU.name) and not has(MEASUREMENT.name)
    except BagError:
        return False
