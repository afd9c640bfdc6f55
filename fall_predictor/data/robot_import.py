"""Datasets from a real robot's recordings: ``ros2 bag record`` of its standard sensor topics.

A robot records ``/joint_states``, ``/imu/data``, ``/left_foot/wrench``, ``/right_foot/wrench``
and ``/robot_description`` (or the URDF is given), and perhaps the package's push topic; there is
no true state. A Unitree humanoid records ``/lowstate`` alone (``ros2 bag record /lowstate``):
its motors named and its IMU taken by the profile's table (``--robot g1_12dof``), its URDF the
profile's unless the recording has one. Each recording becomes one trajectory of a dataset whose features can only come
from the estimated state (``--state estimated``). Its labels come from the same estimator:

* **fallen** when the estimated CoM height drops below ``FALLEN_HEIGHT_FRACTION`` of its
  median over the recording's first ``STANDING_WINDOW_S`` (0.35 m of 0.59 m on the simulated
  robot: a little above the simulator's own 0.33 m rule, so that the estimate's error cannot
  miss a fall in a recording that ends as the robot lands), or the torso's fused tilt from the
  IMU exceeds ``FALLEN_TILT_DEG``; ``t_fallen`` is the first such sample and
  ``t_height_drop`` the start of the CoM's final descent, as for simulated data;
* the push onset ``t_push`` comes from the recording's ``/fall_predictor/push`` message
  (``geometry_msgs/WrenchStamped``, its stamp the onset, its force in the world frame: the
  package's push topic, :data:`~fall_predictor.contract.topics.PUSH`), else from a push-times
  file (:func:`read_push_times`: a CSV of ``bag`` and ``t_push_s`` or ``t_push_ns``, in the
  recording's own stamp time); with both they must agree within :data:`PUSH_AGREEMENT_S`. Then
  alarms before the push are false alarms (method §5) as on simulated data. A push time outside
  the recording, or after its fall, refuses the recording with the reason. A recording with more
  than one push message is refused (a training trajectory holds one push, method §3);
* without a push time, ``t_push`` is the recording's start (``push_source`` ``'unknown'``):
  every alarm on a recording that does not fall is a false alarm, and the lead is measured from
  the recording's start. Training is unaffected (falling states are trained on from
  ``t_height_drop + tau_plus`` only).

A model belongs to the robot it was trained on: the features and the CoM guard are in metres
and kilograms of that robot, so another robot needs recordings (or a simulation) of its own.
"""
from __future__ import annotations

import csv
import json
import math
import os
import shutil
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Iterable, Mapping, Optional, Sequence

import numpy as np

from fall_predictor.profiles.profile import DEFAULT_ROBOT, profile_reference
from fall_predictor.data.bagio import BagError
from fall_predictor.data.dataset import (FORMAT, PUSH_FROM_FILE, PUSH_FROM_TOPIC, PUSH_UNKNOWN,
                                         ROBOT_URDF_FILE, DatasetError, IndexRow, trajectory_id,
                                         write_index_csv)
from fall_predictor.data.outcomes import height_drop_time
from fall_predictor.monitor.fileio import atomic_write_text
from fall_predictor.monitor.records import PUSH_DURATION_S

#: Fallen below this fraction of the standing CoM height (0.35 of 0.59 m on the simulated robot).
FALLEN_HEIGHT_FRACTION = 0.6
#: ... or with the torso tilted beyond this [deg] (fused roll or pitch).
FALLEN_TILT_DEG = 60.0
#: The standing CoM height is the median over this first part of a recording [s].
STANDING_WINDOW_S = 0.5
#: A push time from the file and the recording's push message must agree within this [s].
PUSH_AGREEMENT_S = 0.001
#: The columns of a push-times file: the recording, and its push onset in seconds or nanoseconds.
PUSH_TIMES_COLUMNS = ('bag', 't_push_s', 't_push_ns')


# -- push times -----------------------------------------------------------------------------------
def read_push_times(path: str | os.PathLike) -> dict[str, float]:
    """A push-times file: CSV with a header, columns ``bag`` (a recording as given to
    ``import-bags``, or its directory name) and ``t_push_s`` (the push onset in the recording's
    own stamp time [s]) or ``t_push_ns`` (the same as an integer stamp [ns]); one row per
    recording. Returns ``{bag: t_push [s]}``; DatasetError naming the file and the row for
    anything else (a missing column, a row with both times or neither, a time that is not a
    finite number, a recording named twice)."""
    path = Path(path)
    try:
        with open(path, newline='') as f:
            reader = csv.DictReader(f)
            columns = set(reader.fieldnames or ())
            if 'bag' not in columns or not {'t_push_s', 't_push_ns'} & columns:
                raise DatasetError(f'{path}: a push-times file needs the columns bag and t_push_s (or '
                                   f't_push_ns); it has {", ".join(sorted(columns)) or "none"}')
            table: dict[str, float] = {}
            for line, row in enumerate(reader, start=2):
                bag = (row.get('bag') or '').strip()
                seconds, nanoseconds = ((row.get(c) or '').strip() for c in ('t_push_s', 't_push_ns'))
                where = f'{path}, line {line}'
                if not bag:
                    raise DatasetError(f'{where}: no bag')
                if bool(seconds) == bool(nanoseconds):
                    raise DatasetError(f'{where}: give the push time once, as t_push_s or t_push_ns')
                try:
                    t_push_s = float(seconds) if seconds else int(nanoseconds) / 1e9
                except ValueError:
                    raise DatasetError(f'{where}: {seconds or nanoseconds!r} is not a '
                                       f'{"number" if seconds else "whole number of nanoseconds"}') from None
                if not math.isfinite(t_push_s):
                    raise DatasetError(f'{where}: the push time must be finite, got {seconds!r}')
                key = _bag_key(bag)
                if key in table:
                    raise DatasetError(f'{where}: {bag} is named twice')
                table[key] = t_push_s
    except OSError as error:
        raise DatasetError(f'{path}: {error}') from error
    return table


def _bag_key(bag: str | os.PathLike) -> str:
    """A recording's name as written (a path without a trailing slash)."""
    return str(Path(bag))


def match_push_times(bags: Sequence[str | os.PathLike], table: Mapping[str, float]
                     ) -> tuple[list[Optional[float]], list[str]]:
    """Per recording of ``bags`` (as given on the command line), its push time from ``table``
    (:func:`read_push_times`: by the path as given, else by the directory name), None if it
    has none; and the table's names that matched no recording. DatasetError when a name matches
    several recordings, or a recording is named twice (by its path and by its name)."""
    times: list[Optional[float]] = []
    used: set[str] = set()
    names = [Path(b).name for b in bags]
    for bag, name in zip(bags, names):
        keys = [k for k in dict.fromkeys((_bag_key(bag), name)) if k in table]
        if len(keys) > 1:
            raise DatasetError(f'{bag}: the push-times file names it twice ({" and ".join(keys)})')
        if keys and keys[0] == name and names.count(name) > 1 and _bag_key(bag) != name:
            raise DatasetError(f'the push-times file\'s {name} names {names.count(name)} recordings: '
                               'give their paths')
        times.append(table[keys[0]] if keys else None)
        used.update(keys)
    return times, [k for k in table if k not in used]


@dataclass(frozen=True)
class RecordedPush:
    """A recording's push: onset [s] in its stamp time, where it comes from, the world force [N]
    when its message gave one."""

    t_s: float
    source: str
    force_world_n: Optional[np.ndarray] = field(default=None, compare=False)


def push_of_recording(bag: Path, t_push_file_s: Optional[float] = None) -> Optional[RecordedPush]:
    """The push of a robot's recording (module docs): its ``/fall_predictor/push`` message, else
    ``t_push_file_s`` [s] from a push-times file, else None. DatasetError when it holds more than
    one push message, a malformed one, or one the file's time disagrees with."""
    from fall_predictor.contract.topics import PUSH
    from fall_predictor.contract.wire import WireFormatError
    from fall_predictor.data.bagio import decode, iter_messages

    pushes = []
    for message in iter_messages(bag, (PUSH.name,)):
        if message.msg_type != PUSH.msg_type:
            raise DatasetError(f'{bag}: {PUSH.name} has type {message.msg_type}, expected {PUSH.msg_type}')
        try:
            pushes.append(decode(message))
        except WireFormatError as error:
            raise DatasetError(f'{bag}: malformed {PUSH.name} message: {error}') from error
    if len(pushes) > 1:
        raise DatasetError(f'{bag}: {len(pushes)} pushes recorded on {PUSH.name}; a training '
                           'trajectory holds exactly one (method §3)')
    if pushes:
        push = pushes[0]
        if t_push_file_s is not None and abs(t_push_file_s - push.t) > PUSH_AGREEMENT_S:
            raise DatasetError(f'{bag}: the push-times file says {t_push_file_s:.6f} s, its {PUSH.name} '
                               f'message {push.t:.6f} s (stamp time of the recording)')
        return RecordedPush(float(push.t), PUSH_FROM_TOPIC, np.asarray(push.force, dtype=float))
    if t_push_file_s is not None:
        return RecordedPush(float(t_push_file_s), PUSH_FROM_FILE)
    return None


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
                        robot: str = DEFAULT_ROBOT, t_push_file_s: Optional[float] = None) -> IndexRow:
    """The index row of one robot recording, labelled from the estimated state, its push time
    from its push message or ``t_push_file_s`` [s] (module docs)."""
    from fall_predictor.data.estimation import estimated_measurements
    from fall_predictor.data.sensorbag import read_imu, read_robot_description
    from fall_predictor.monitor.geometry import fused_roll_pitch

    if urdf is None:
        urdf = read_robot_description(bag) or lowstate_urdf(bag, robot)
        if urdf is None:
            raise DatasetError(f'{bag}: no /robot_description in the recording; give the URDF (--urdf)')
    ms = estimated_measurements(bag, urdf=urdf, robot=robot)
    if len(ms) < 2:
        from fall_predictor.data.sensorbag import STREAM_TOPICS
        from fall_predictor.profiles.profile import load_profile
        streams = ('joints', 'imu', *load_profile(robot).sensor_layout().force_sensors)
        needed = [STREAM_TOPICS[stream].name for stream in streams]
        raise DatasetError(f'{bag}: the estimator gave {len(ms)} states; the {robot} robot needs '
                           f'{", ".join(needed)}')
    t = np.array([m.t for m in ms])
    z = np.array([m.com[2] for m in ms])
    standing = float(np.median(z[t <= t[0] + STANDING_WINDOW_S]))
    t_imu, quat, _ = read_imu(bag, robot)
    tilt = np.degrees(np.max(np.abs(fused_roll_pitch(quat)), axis=1))
    tilted = tilt[np.clip(np.searchsorted(t_imu, t), 0, len(t_imu) - 1)] > FALLEN_TILT_DEG
    fallen = (z < FALLEN_HEIGHT_FRACTION * standing) | tilted
    t_fallen = float(t[np.argmax(fallen)]) if fallen.any() else None
    t0, nan = float(t[0]), float('nan')
    push = push_of_recording(bag, t_push_file_s)
    force_n = angle_deg = nan
    if push is None:
        t_push, t_force_end, source = t0, t0, PUSH_UNKNOWN
    else:
        t_push, source = push.t_s, push.source
        if not t0 <= t_push <= float(t[-1]):
            raise DatasetError(f'{bag}: the push at {t_push:.6f} s ({push.source}) is outside the '
                               f'recording, {t0:.6f} to {float(t[-1]):.6f} s (its own stamp time)')
        if t_fallen is not None and t_push >= t_fallen:
            raise DatasetError(f'{bag}: the push at {t_push:.6f} s ({push.source}) comes after the '
                               f'robot fell at {t_fallen:.6f} s')
        t_force_end = round(t_push + PUSH_DURATION_S, 6)
        if push.force_world_n is not None:
            heading = ms[min(int(np.searchsorted(t, t_push)), len(ms) - 1)].heading
            force_n = float(np.hypot(*push.force_world_n[:2]))
            angle = math.degrees(math.atan2(push.force_world_n[1], push.force_world_n[0]) - heading)
            angle_deg = float((angle + 180.0) % 360.0 - 180.0)
    return IndexRow(trajectory_id=tid, bag=f'bags/{tid}', force_n=force_n, angle_deg=angle_deg,
                    height_m=nan, t_push=t_push, t_force_end=t_force_end,
                    fallen=t_fallen is not None, t_fallen=t_fallen,
                    t_height_drop=None if t_fallen is None else height_drop_time(t, z, t_fallen),
                    t_reflex=None, t_start=t0, t_end=float(t[-1]), samples=len(ms),
                    push_source=source)


def import_robot_recordings(bags: Iterable[str | os.PathLike], out: str | os.PathLike,
                            urdf: Optional[str] = None, robot: str = DEFAULT_ROBOT,
                            push_times: Optional[Mapping[str, float]] = None
                            ) -> tuple[list[IndexRow], dict[str, str]]:
    """A new dataset directory ``out`` from robot recordings (module docs) of the robot whose
    profile is ``robot`` (name or path), their push times from their push messages or
    ``push_times`` (:func:`read_push_times`, matched by :func:`match_push_times`); returns its
    rows and the recordings rejected, with the reason."""
    out = Path(out)
    if out.exists():
        raise DatasetError(f'{out}: exists; import into a new directory')
    given = list(bags)
    file_times, unused = match_push_times(given, push_times or {})
    sources = [Path(b).resolve() for b in given]
    (out / 'bags').mkdir(parents=True)
    (out / 'index').mkdir()
    rows, rejected, described, profile_urdf = [], {}, None, None
    for source, t_push_file_s in zip(sources, file_times):
        tid = trajectory_id(len(rows))
        try:
            row = robot_recording_row(source, tid, urdf, robot, t_push_file_s)
            from fall_predictor.data.sensorbag import read_robot_description
            recorded = urdf or read_robot_description(source)
            if recorded is None and profile_urdf is None:
                profile_urdf = lowstate_urdf(source, robot)     # a Unitree robot's: its profile's
            if described is None:
                described = robot_from_urdf(recorded or profile_urdf)
        except (DatasetError, BagError) as error:
            rejected[str(source)] = str(error)
            continue
        shutil.copytree(source, out / 'bags' / tid, copy_function=shutil.copy2)
        atomic_write_text(out / 'index' / f'{tid}.json', json.dumps(asdict(row), sort_keys=True))
        rows.append(row)
    manifest = {'format': FORMAT, 'source': 'robot_recordings', 'bags': [str(s) for s in sources],
                'robot': None if described is None else {**described, 'profile': profile_reference(robot)},
                'ground_truth': False, 'sensors': {'recorded_on': 'robot'},
                'fall_rule': {'height_fraction': FALLEN_HEIGHT_FRACTION, 'tilt_deg': FALLEN_TILT_DEG,
                              'standing_window_s': STANDING_WINDOW_S},
                'push_times': {source: sum(r.push_source == source for r in rows)
                               for source in (PUSH_FROM_TOPIC, PUSH_FROM_FILE, PUSH_UNKNOWN)}}
    if unused:
        manifest['push_times']['file_entries_unused'] = unused
    if urdf is None:
        urdf = profile_urdf
    if urdf is not None:                 # recordings without /robot_description
        atomic_write_text(out / ROBOT_URDF_FILE, urdf)
        manifest['urdf_file'] = ROBOT_URDF_FILE
    atomic_write_text(out / 'dataset.json', json.dumps(manifest, indent=1))
    write_index_csv(out, rows)
    return rows, rejected


def lowstate_urdf(bag: Path, robot: str) -> Optional[str]:
    """A Unitree humanoid's recording has no ``/robot_description`` (the robot publishes none):
    the URDF of its profile, as the estimator node publishes it; None for other recordings
    (DatasetError when the profile has no motor table for it)."""
    from fall_predictor.contract.unitree_hg import LOWSTATE
    from fall_predictor.data.bagio import iter_messages
    from fall_predictor.profiles.profile import load_profile
    if next(iter(iter_messages(Path(bag), (LOWSTATE.name,))), None) is None:
        return None
    profile = load_profile(robot)
    if profile.unitree_hg is None:
        raise DatasetError(f'{bag}: {LOWSTATE.name} names its motors by index only: give the '
                           'robot profile with their table (--robot g1, or g1_12dof for the '
                           '12-joint policy)')
    return profile.urdf_xml()


def is_robot_recording(bag: str | os.PathLike) -> bool:
    """Whether a bag is a robot's recording: an IMU topic (or a Unitree humanoid's
    ``/lowstate``) and no simulator measurement topic."""
    from fall_predictor.data.bagio import iter_messages
    from fall_predictor.contract.topics import IMU, MEASUREMENT
    from fall_predictor.contract.unitree_hg import LOWSTATE

    def has(topic: str) -> bool:
        return next(iter(iter_messages(Path(bag), (topic,))), None) is not None
    try:
        return (has(IMU.name) or has(LOWSTATE.name)) and not has(MEASUREMENT.name)
    except BagError:
        return False
