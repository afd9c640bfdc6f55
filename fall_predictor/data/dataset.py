"""Push-trajectory datasets as they are read: manifest, index and features.

Layout of a dataset directory (made by :mod:`fall_predictor.data.generation`)::

    dataset.json              manifest: format, seed, push distribution, horizon, robot
    bags/traj_00042/          one rosbag2 bag (MCAP) per trajectory
    index/traj_00042.json     its index row, written only once the bag is complete
    index.csv                 all rows in one table (rewritten after each run)
    costs/traj_00042.json     what simulating it cost, and where (:mod:`fall_predictor.data.generation_cost`)
    cache/traj_00042.npz      features derived from the bag's true state (:mod:`fall_predictor.data.cache`)
    cache/traj_00042.estimated.npz   features of the state estimated from its sensor topics

Features come from one of two states (``state``): ``'true'``, the simulator's exact state on
``/fall_predictor/measurement``; or ``'estimated'``, the state the
:class:`~fall_predictor.monitor.estimator.StateEstimator` (the class the live
``state_estimator_node`` runs, with the same default configuration) estimates from the bag's
sensor topics. Labels (pushes, falls) always come from the true state.

A sample the estimator or the feature extractor refuses is a hole in the data, as it is onboard
(``monitor/chain.py``: a DEGRADED state, no prediction): an estimate the estimator could not make
or would not trust (a sensor missing, a fallen robot's CoM dead-reckoned below the ground), a
measurement the :class:`~fall_predictor.monitor.features.FeatureExtractor` refuses (a jump faster
than physics allows, a time that does not increase). It is left out of the features, counted per
trajectory (:class:`RefusedSamples`, :attr:`LoadReport.refused`) and never an error; the history
window spans such a hole as the onboard monitor does (:mod:`fall_predictor.learning.metrics`).

A bag that cannot be read is reported with its file named and skipped; the rest of the dataset
stays usable.
"""
from __future__ import annotations

import csv
import functools
import hashlib
import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Iterable, Optional, Sequence

import numpy as np

from fall_predictor.data.bagio import BagError, read_trajectory
from fall_predictor.data.cache import bag_fingerprint, cached_arrays, derivation_key, files_fingerprint
from fall_predictor.data.outcomes import unsettled_at_horizon
from fall_predictor.data.refused_samples import (RefusedSamples, _refused_arrays, refused_samples,
                                                 usable_features)
from fall_predictor.monitor.features import FeatureSettings
from fall_predictor.monitor.fileio import atomic_output
from fall_predictor.monitor.records import (FEATURE_NAMES, N_FEATURES, Measurement, PushSpec,
                                            TrajectoryFeatures)

FORMAT = 'fall_predictor/dataset/v1'
#: Feature columns of the horizontal momentum (whether a trajectory settled, data/outcomes.py).
LIN_MOM_X, LIN_MOM_Y = FEATURE_NAMES.index('lin_mom_x'), FEATURE_NAMES.index('lin_mom_y')
# v3: LR lateral edges fold FRONT/BACK; v4: + cp; v5: + the base's attitude; v6: its angular
# velocity from its turn (v5: differenced fused angles); v7: refused samples left out and counted
CACHE_FORMAT = 'fall_predictor/features-cache/v7'
#: The robot's URDF of an imported robot dataset whose bags hold no /robot_description.
ROBOT_URDF_FILE = 'robot.urdf'
#: Where features can come from (module docs); the CLI default is ``'estimated'``.
STATES = ('estimated', 'true')
#: What can disturb a run (:attr:`IndexRow.cause`): a push, a trip over an obstacle, a slip on a
#: low-friction patch, a step down or up or an incline, an actuator fault on a leg joint, and a
#: long walk with changing commands and no disturbance (sim/disturbances.py describes each).
CAUSE_PUSH, CAUSE_TRIP, CAUSE_SLIP, CAUSE_STEP, CAUSE_FAULT, CAUSE_WALK = (
    'push', 'trip', 'slip', 'step', 'fault', 'walk')
CAUSES = (CAUSE_PUSH, CAUSE_TRIP, CAUSE_SLIP, CAUSE_STEP, CAUSE_FAULT, CAUSE_WALK)


class DatasetError(Exception):
    """A dataset directory that cannot be used as asked (names the path and the problem)."""


@dataclass
class IndexRow:
    """One trajectory of the index. Times in simulation seconds; None where not applicable."""

    trajectory_id: str
    bag: str                      #: bag directory relative to the dataset directory
    force_n: float
    angle_deg: float
    height_m: float
    t_push: float
    t_force_end: float
    fallen: bool
    t_fallen: Optional[float]
    t_height_drop: Optional[float]
    t_reflex: Optional[float]
    t_start: float
    t_end: float
    samples: int
    #: The gait walked before the push (method §3 amendment); None in datasets without gait variety.
    gait_speed_m_s: Optional[float] = None
    gait_single_support_s: Optional[float] = None
    gait_step_width_m: Optional[float] = None
    gait_standing: Optional[bool] = None
    #: The velocity a learned policy was commanded to walk at (None: C_bal's datasets).
    command_vx_m_s: Optional[float] = None
    command_vy_m_s: Optional[float] = None
    command_yaw_rate_rad_s: Optional[float] = None
    #: Where ``t_push`` comes from in a robot's recordings (data/robot_import.py): its push
    #: topic (:data:`PUSH_FROM_TOPIC`), a push-times file (:data:`PUSH_FROM_FILE`), or nowhere
    #: (:data:`PUSH_UNKNOWN`: ``t_push`` is the recording's start). None: as the dataset was
    #: made (a simulated push, a recorder's push topic; unknown in a robot's recordings imported
    #: before this field): :func:`push_time_known`.
    push_source: Optional[str] = None
    #: What disturbed the run (:data:`CAUSES`); every dataset made before causes existed holds
    #: pushes. A run of another cause keeps the push fields at a zero force, ``t_push`` and
    #: ``t_force_end`` at its onset (none for a long walk: its start).
    cause: str = CAUSE_PUSH
    #: The cause's parameters as JSON text (an object; the push's are its own fields): e.g. a
    #: trip's obstacle, a slip's patch friction, a fault's joint and profile (sim/disturbances.py).
    cause_params: Optional[str] = None
    #: When the disturbance first acted [s], measured in the run: the push's onset, the first
    #: contact with the obstacle or patch, the edge crossed, the fault's start; None for a long
    #: walk (no disturbance) and in datasets made before causes existed (:attr:`onset_s`).
    t_onset: Optional[float] = None
    #: The run's randomised world as JSON text (sim/randomization.WorldRandomization: friction,
    #: masses, drives, sensor latency and IMU bias; ``generate --randomize``); None: nominal.
    randomization: Optional[str] = None

    @property
    def push(self) -> PushSpec:
        return PushSpec(self.force_n, self.angle_deg, self.height_m, self.t_push,
                        round(self.t_force_end - self.t_push, 6))

    @property
    def onset_s(self) -> Optional[float]:
        """When the disturbance first acted [s]: ``t_onset``, or a push's ``t_push`` in rows
        made before ``t_onset`` existed; None for a run no disturbance acted on."""
        if self.t_onset is not None:
            return self.t_onset
        return self.t_push if self.cause == CAUSE_PUSH else None

    @property
    def params(self) -> dict[str, Any]:
        """The cause's parameters (``cause_params`` parsed; {} when none)."""
        if not self.cause_params:
            return {}
        params = json.loads(self.cause_params)
        if not isinstance(params, dict):
            raise DatasetError(f'{self.trajectory_id}: cause_params is not a JSON object')
        return params


def cause_params_text(params: dict[str, Any]) -> str:
    """``params`` as :attr:`IndexRow.cause_params` stores them (sorted keys, compact)."""
    return json.dumps(params, sort_keys=True, separators=(',', ':'))


#: :attr:`IndexRow.push_source` values.
PUSH_FROM_TOPIC, PUSH_FROM_FILE, PUSH_UNKNOWN = 'push_topic', 'push_times_file', 'unknown'


def push_time_known(row: IndexRow, robot_recordings: bool) -> bool:
    """Whether ``row.t_push`` is a push's onset, not the recording's start standing in for an
    unknown one (``robot_recordings``: the dataset holds a robot's recordings, whose rows made
    before :attr:`IndexRow.push_source` existed had no push time)."""
    if row.push_source is None:
        return not robot_recordings
    return row.push_source != PUSH_UNKNOWN


def is_robot_recordings(manifest: dict[str, Any]) -> bool:
    """Whether a dataset's manifest is that of a robot's own recordings (no true state)."""
    return manifest.get('ground_truth') is False


def trajectory_id(index: int) -> str:
    return f'traj_{index:05d}'


def read_manifest(out: str | os.PathLike) -> dict[str, Any]:
    """The dataset's ``dataset.json``: how it was made, and the robot it was made with."""
    path = Path(out) / 'dataset.json'
    if not path.exists():
        raise DatasetError(f'{out}: not a dataset directory (no dataset.json)')
    try:
        manifest = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise DatasetError(f'{path}: unreadable manifest: {exc}') from exc
    if not isinstance(manifest, dict) or manifest.get('format') != FORMAT:
        raise DatasetError(f'{path}: not a {FORMAT} manifest')
    return manifest


def has_sensor_topics(out: str | os.PathLike) -> bool:
    """Whether the dataset was recorded with the robot's sensor topics (``generate --sensor-noise``)."""
    return 'sensors' in read_manifest(out)


def resolve_state(out: str | os.PathLike, requested: str) -> tuple[str, Optional[str]]:
    """The state features of ``out`` are computed from, and a note when it is not ``requested``.

    ``'estimated'`` on a dataset recorded without sensor topics falls back to ``'true'`` (there
    is nothing to estimate from) and says so; an unknown state raises ``ValueError``.
    """
    if requested not in STATES:
        raise ValueError(f'state must be one of {STATES}, got {requested!r}')
    if requested == 'true' and read_manifest(out).get('ground_truth') is False:
        raise DatasetError(f'{out} holds a robot\'s recordings: there is no true state; use --state estimated')
    if requested == 'estimated' and not has_sensor_topics(out):
        return 'true', (f'{out} was recorded without sensor topics: features from the true state '
                        '(record them with `generate --sensor-noise 1` to train on estimated state)')
    return requested, None


def robot_total_mass_kg(out: str | os.PathLike) -> float:
    """The total mass [kg] of the robot a dataset was recorded with (from its manifest)."""
    try:
        mass = float(read_manifest(out)['robot']['total_mass_kg'])
    except (KeyError, TypeError, ValueError) as exc:
        raise DatasetError(f'{out}: dataset.json does not give the robot\'s total mass '
                           '(robot.total_mass_kg); regenerate or re-import the dataset') from exc
    if not (mass > 0.0 and np.isfinite(mass)):
        raise DatasetError(f'{out}: robot.total_mass_kg must be positive, got {mass}')
    return mass


def read_index(out: str | os.PathLike) -> list[IndexRow]:
    """All finished trajectories of a dataset, in index order."""
    out = Path(out)
    if not (out / 'dataset.json').exists():
        raise DatasetError(f'{out}: not a dataset directory (no dataset.json)')
    rows = []
    for path in sorted((out / 'index').glob('traj_*.json')):
        try:
            row = IndexRow(**json.loads(path.read_text()))
        except (OSError, json.JSONDecodeError, TypeError) as exc:
            raise DatasetError(f'{path}: unreadable index row: {exc}') from exc
        if row.cause not in CAUSES:
            raise DatasetError(f'{path}: unknown cause {row.cause!r} (one of {", ".join(CAUSES)})')
        rows.append(row)
    return rows


def write_index_csv(out: Path, rows: Iterable[IndexRow]) -> Path:
    path = Path(out) / 'index.csv'
    rows = list(rows)
    names = list(IndexRow.__dataclass_fields__)
    with atomic_output(path) as tmp, open(tmp, 'w', newline='') as f:
        writer = csv.DictWriter(f, fieldnames=names)
        writer.writeheader()
        for row in rows:
            writer.writerow(asdict(row))
    return path


# -- feature cache ------------------------------------------------------------------------------
@dataclass
class LoadReport:
    """What :func:`load_features` found: usable trajectories and the bags it had to skip."""

    trajectories: list[TrajectoryFeatures]
    errors: dict[str, str]           #: trajectory id -> error message (bag named)
    rebuilt: int                     #: cache entries (re)computed from bags
    fingerprint: str                 #: of the whole dataset as loaded
    settings: FeatureSettings        #: how the features were computed
    state: str = 'true'              #: 'true' or 'estimated' (module docs)
    note: Optional[str] = None       #: why ``state`` differs from the one asked for
    #: trajectory id -> why it is left out: not fallen, but not settled when its recording
    #: ended (:func:`~fall_predictor.data.outcomes.unsettled_at_horizon`; method §4)
    unsettled: dict[str, str] = field(default_factory=dict)
    #: trajectory id -> the samples left out of it as holes (module docs), for those with any
    refused: dict[str, RefusedSamples] = field(default_factory=dict)

    @property
    def refused_total(self) -> RefusedSamples:
        """The refused samples of all the trajectories loaded, summed."""
        return RefusedSamples.summed(self.refused.values())


def _measurements(bag: Path, state: str) -> tuple[list[Measurement], list[tuple[float, str]]]:
    """The measurements of a bag's ``state`` and the estimates the estimator refused (none for
    the true state)."""
    if state == 'true':
        return read_trajectory(bag).measurements or [], []
    # Imported here: Pinocchio is loaded only by those who estimate.
    from fall_predictor.data.estimation import estimated_run
    data_dir = bag.parent.parent                              # DATA/bags/<id> -> DATA
    urdf_file = data_dir / ROBOT_URDF_FILE
    run = estimated_run(bag, urdf=urdf_file.read_text() if urdf_file.exists() else None,
                        robot=dataset_robot(data_dir))
    return run.measurements, run.refused


def dataset_robot(data_dir: Path) -> str:
    """The robot profile (name or path) of a dataset's robot: its manifest's ``robot.profile``, else
    its ``robot.name`` when a shipped profile has that name; the default robot for a dataset whose
    manifest names no robot (made before robots had names). A robot named but neither shipped nor
    given by a profile file is a :class:`DatasetError`: estimating it with another robot's
    profile would be silently wrong."""
    from fall_predictor.profiles.profile import DEFAULT_ROBOT, available_profiles
    try:
        robot = json.loads((data_dir / 'dataset.json').read_text()).get('robot') or {}
    except (OSError, ValueError):
        return DEFAULT_ROBOT
    if robot.get('profile'):
        return str(robot['profile'])
    name = robot.get('name')
    if name is None:
        return DEFAULT_ROBOT
    if name not in available_profiles():
        raise DatasetError(
            f'{data_dir}: the dataset\'s robot {name!r} is not a shipped profile '
            f'({", ".join(available_profiles())}) and its manifest names no profile file: add '
            f'"profile": "/path/to/profile.yaml" to "robot" in {data_dir / "dataset.json"} '
            '(generate records it when --robot is a path)')
    return name


def dataset_guard_com_height_m(data_dir: str | os.PathLike) -> float:
    """The CoM guard [m] of the robot a dataset was recorded with (method §6): its profile's
    ``monitor.guard_com_height_m`` (:func:`dataset_robot`), the guard every offline tool trains,
    evaluates, sweeps and cross-validates that dataset with unless told otherwise. A profile that
    cannot be loaded is a :class:`DatasetError` naming the dataset."""
    from fall_predictor.profiles.profile import ProfileError, load_profile
    robot = dataset_robot(Path(data_dir))
    try:
        return load_profile(robot).guard_com_height_m
    except ProfileError as exc:
        raise DatasetError(f'{data_dir}: the robot profile {robot!r} of the dataset: {exc}') from exc


@functools.lru_cache(maxsize=64)
def _profile_fingerprint(data_dir: Path) -> str:
    """Fingerprint of what the estimator reads of the dataset's robot profile: its YAML as parsed,
    less the models it names, and the files beside it (the estimator reads the sole frames,
    bounds and URDF from them). Which model a robot runs changes no feature, nor does a comment:
    making another model a profile's default derives no dataset's features again."""
    from fall_predictor.profiles.profile import ProfileError, profile_path
    try:
        source = profile_path(dataset_robot(data_dir))
        beside = files_fingerprint(f for f in source.parent.iterdir() if f.is_file() and f != source)
        text = source.read_text(encoding='utf-8')
    except (ProfileError, OSError):
        return 'none'
    return f'{beside}{_profile_content_fingerprint(text)}'


#: The profile key that names a model file, at its top and in each controller's entry.
_MODEL_KEY = 'model'


def _without_model(entry: Any) -> Any:
    return {k: v for k, v in entry.items() if k != _MODEL_KEY} if isinstance(entry, dict) else entry


def _profile_content_fingerprint(text: str) -> str:
    """Fingerprint of a profile's YAML content without its comments and the models it names;
    of the text itself when it is not a YAML mapping (loading the profile says why elsewhere)."""
    import yaml
    try:
        content = yaml.safe_load(text)
    except yaml.YAMLError:
        content = None
    if not isinstance(content, dict):
        return hashlib.sha256(text.encode()).hexdigest()[:16]
    content = _without_model(content)
    if isinstance(content.get('controllers'), dict):
        content['controllers'] = {name: _without_model(e) for name, e in content['controllers'].items()}
    return hashlib.sha256(json.dumps(content, sort_keys=True, default=str).encode()).hexdigest()[:16]


def cached_bag_arrays(data_dir: Path, bag: str, name: str, kind: str, compute,
                      derived_by: Sequence[str]) -> dict[str, np.ndarray]:
    """Arrays of ``kind`` derived by the modules ``derived_by`` from one bag of a dataset,
    cached as ``DATA/cache/<name>.npz`` (:func:`~fall_predictor.data.cache.cached_arrays`,
    keyed to that code); a bag that cannot be read is a :class:`DatasetError` naming it."""
    bag_dir = Path(data_dir) / bag
    try:
        arrays, _ = cached_arrays(Path(data_dir) / 'cache' / f'{name}.npz', bag_dir,
                                  derivation_key(kind, derived_by), compute)
    except OSError as error:
        raise DatasetError(f'{bag_dir}: {error}') from error
    except BagError as error:
        raise DatasetError(str(error)) from error
    return arrays


def _total_mass_or_none(out: Path) -> Optional[float]:
    try:
        return robot_total_mass_kg(out)
    except DatasetError:
        return None


def cached_feature_arrays(out: Path, row: IndexRow, settings: FeatureSettings = FeatureSettings(),
                          state: str = 'true') -> tuple[dict[str, np.ndarray], bool]:
    """The derived arrays of one trajectory (from its cache entry when up to date) and whether
    they were computed now: ``t`` [s], features ``X``, contact ``mode``, the base's ``attitude``
    (method §8c), ``foot_force_n`` and the capture point's signed distance to the support polygon
    ``cp_distance_m`` (NaN when the dataset gives no robot mass), all from the same ``state``,
    at the samples neither the estimator nor the feature extractor refused; and the record of
    those (:func:`refused_samples`). Raises OSError or BagError."""
    from fall_predictor.monitor.capture_point import capture_point_distances

    bag = out / row.bag

    def from_bag() -> dict[str, np.ndarray]:
        measured, refused_estimates = _measurements(bag, state)
        if not measured:
            raise BagError(f'{bag}: no {state} state to compute features from')
        kept, inputs, mode, refused_features = usable_features(measured, settings)
        if not kept.size:
            raise BagError(f'{bag}: the feature extractor refused every sample, the first: '
                           f'{refused_features[0][1]}')
        ms = [measured[i] for i in kept]
        foot_force = np.array([[m.left_contacts[:, 2].sum(), m.right_contacts[:, 2].sum()] for m in ms])
        mass = _total_mass_or_none(out)
        cp = capture_point_distances(ms, mass) if mass is not None else np.full(len(ms), np.nan)
        return {'t': np.array([m.t for m in ms]), 'X': inputs[:, :N_FEATURES], 'mode': mode,
                'attitude': inputs[:, N_FEATURES:],
                'foot_force_n': foot_force.reshape(len(ms), 2), 'cp_distance_m': cp,
                **_refused_arrays(refused_estimates, refused_features)}

    # Features computed with other settings, other code or another robot profile are another
    # kind of derived data.
    kind = derivation_key(CACHE_FORMAT, (__name__,), f'settings={json.dumps(asdict(settings), sort_keys=True)}',
                          f'state={state}', *([] if state == 'true' else [f'profile={_profile_fingerprint(out)}']))
    name = row.trajectory_id + ('' if state == 'true' else f'.{state}')
    return cached_arrays(out / 'cache' / f'{name}.npz', bag, kind, from_bag)


def _load_or_build(out: Path, row: IndexRow, settings: FeatureSettings, state: str = 'true'
                   ) -> tuple[Optional[TrajectoryFeatures], Optional[str], bool, RefusedSamples]:
    """Features of one trajectory (cached), or the error that kept them from being read; whether
    they were computed now, and the samples refused."""
    bag = out / row.bag
    try:
        arrays, built = cached_feature_arrays(out, row, settings, state)
    except OSError as exc:
        return None, f'{bag}: {exc}', False, RefusedSamples()
    except BagError as exc:
        return None, str(exc), False, RefusedSamples()
    return TrajectoryFeatures(row.trajectory_id, arrays['t'], arrays['X'], arrays['mode'], row.fallen,
                              row.t_push, row.t_force_end, row.t_fallen, row.t_height_drop,
                              arrays['foot_force_n'], arrays['attitude']), None, built, \
        refused_samples(arrays)


def load_features(data_dir: str | os.PathLike, jobs: int = 1, progress: bool = True,
                  settings: FeatureSettings = FeatureSettings(), state: str = 'true') -> LoadReport:
    """Features of every trajectory of a dataset, from the cache where it is up to date.

    ``state`` is ``'true'`` or ``'estimated'`` (module docs; see :func:`resolve_state` for a
    dataset without sensor topics). A bag that cannot be read is reported in ``errors`` (with
    its file named) and skipped; the rest of the dataset stays usable. Samples the estimator or
    the feature extractor refuses are holes, counted in ``refused`` (module docs).
    """
    from joblib import delayed
    from tqdm import tqdm

    from fall_predictor.data.parallel import local_parallel

    out = Path(data_dir)
    rows = read_index(out)
    if not rows:
        raise DatasetError(f'{out}: the dataset has no finished trajectories')
    state, note = resolve_state(out, state)
    desc = 'features' if state == 'true' else 'estimation + features'
    results = local_parallel(jobs)(delayed(_load_or_build)(out, row, settings, state)
                                   for row in tqdm(rows, desc=desc, unit='traj', disable=not progress))
    trajectories, errors, rebuilt, unsettled, refused = [], {}, 0, {}, {}
    mass_kg = _mass_or_none(out)
    h = hashlib.sha256()
    for row, (traj, error, built, holes) in zip(rows, results):
        if traj is None:
            errors[row.trajectory_id] = error
            continue
        rebuilt += int(built)
        h.update(f'{row.trajectory_id}:{bag_fingerprint(out / row.bag)};'.encode())
        why = None if traj.fallen or mass_kg is None else unsettled_at_horizon(
            traj.t, traj.X[:, [LIN_MOM_X, LIN_MOM_Y]], traj.t_push, mass_kg)
        if why is not None:
            unsettled[row.trajectory_id] = why
            continue
        trajectories.append(traj)
        if holes.total:
            refused[row.trajectory_id] = holes
    return LoadReport(trajectories, errors, rebuilt, h.hexdigest()[:16], settings, state, note,
                      unsettled, refused)


def _mass_or_none(out: Path) -> Optional[float]:
    """The robot's mass, or None for a dataset whose manifest does not give it (then no
    trajectory is checked for settling)."""
    try:
        return robot_total_mass_kg(out)
    except DatasetError:
        return None
