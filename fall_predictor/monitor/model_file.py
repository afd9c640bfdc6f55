"""The model file: a learned predictor's decision lists and provenance as plain JSON.

Layout (schema ``fall_predictor.decision_lists``, version 6)::

    {
      "schema": "fall_predictor.decision_lists",
      "schema_version": 6,
      "feature_names": ["com_x", ..., "d_ang_mom_z"],          # must equal FEATURE_NAMES
      "input_names": ["com_x", ..., "d_ang_mom_z"],            # FEATURE_NAMES, or with the
                                                              # attitude after them (version 6)
      "contact_mode_names": ["LR-INSIDE", ..., "OUTSIDE"],    # must equal CONTACT_MODE_NAMES
      "lists": [                                              # one per contact mode, in order
        {"mode": "LR-INSIDE", "default": "balanced",
         "rules": [{"label": "falling",
                    "conditions": [{"feature": 2, "op": "<=", "threshold": 0.35}, ...]}, ...]},
        ...
      ],
      "features": {"rate_window_s": 0.01, "edge_tolerance_m": 0.01,   # FeatureSettings: how
                   "sample_period_s": 0.001, "guard_com_height_m": 0.48}, # the monitor must compute
      "training": {"tau_plus_s": -0.25, "balanced_weight": 4.0, "falling_weight": 1.0,
                   "sample_stride": 10, "learner": {"name": "TreeListLearner", "params": {...}},
                   "state": "estimated", "mirror": false},   # optional; absent = "true", false
      "recommended_tau_his_s": 0.06,                          # or null
      "dataset_fingerprint": "...",
      "created": {"utc": "2025-01-01T00:00:00Z", "package_version": "0.1.0"},
      "robot_mass_kg": <kg>,                                  # the training robot's; or null (version 3)
      "time_to_fall": {"trees": [...16, tree or null], "fallback": tree},  # or null (version 3);
                      # version 7: or {"kind": "boosted", "bias": 0.6, "trees": [tree, ...]}
      "fall_direction": {"inputs": [...8 names], "bias": 0.0, "trees": [tree, ...]}  # or null (5)
    }

Version 7 lets ``time_to_fall`` be boosted trees over the 15 features fitted from each trigger to
fallen (method §8d; :class:`~fall_predictor.monitor.boosted_trees.BoostedTimeToFall`, the same
``predict_one(x, mode)``) instead of the per-mode trees.
Version 6 added ``input_names``: what a classifier reads, the 15 features or the 19 inputs
:data:`~fall_predictor.monitor.records.INPUT_NAMES_WITH_ATTITUDE` (the features, then the base's
attitude, method §8c; boosted trees only); older files read the 15 features.
Version 5 added ``fall_direction``: a learned fall direction
(:class:`~fall_predictor.monitor.fall_direction.LearnedDirection`, returned as
``metadata.fall_direction``; None: the monitor gives the momentum's direction).

Version 4 lets a mode's entry be boosted trees instead of a list (method §8a;
:mod:`fall_predictor.monitor.boosted_trees`): ``{"mode": "LR-INSIDE", "boosted_trees":
{"bias": -2.3, "decision_threshold": 1.0, "trees": [{"feature": [...], "threshold": [...],
"left": [...], "right": [...], "value": [...]}, ...]}}``; version 2 and 3 files still load.
Version 3 added ``robot_mass_kg`` (for the capture-point fall direction,
:mod:`fall_predictor.monitor.fall_direction`) and ``time_to_fall`` (the per-mode regression
trees of :mod:`fall_predictor.monitor.time_to_fall`); version 2 files still load, with both
None. :func:`load_model` returns them as ``metadata.robot_mass_kg`` and
``metadata.time_to_fall`` (a :class:`~fall_predictor.monitor.time_to_fall.TimeToFallRegressor`:
``metadata.time_to_fall.predict_one(x, mode)`` is the seconds left until fallen).

``feature`` is a column index into ``feature_names``; ``op`` is ``"<="`` or ``">"``.
Loading only parses JSON (never executes anything) and validates every field: a malformed or
truncated file, another schema or version, different feature or mode names, an out-of-range
feature index, a non-finite threshold, an unknown operator or class, or a missing or unknown
key raises :class:`ModelFileError` naming the file and the offending field.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Optional, Union

from fall_predictor import __version__
from fall_predictor.errors import TeamFileError
from fall_predictor.monitor.features import FeatureSettings
from fall_predictor.monitor.fileio import atomic_output, read_regular_file
from fall_predictor.monitor.decision_list import (COMPARISON_OPS, Condition, DecisionList,
                                          PerModeDecisionLists, Rule)
from fall_predictor.monitor.boosted_trees import (BoostedTimeToFall, BoostedTrees,
                                                  BoostedTreesError)
from fall_predictor.monitor.fall_direction import FallDirectionError, LearnedDirection
from fall_predictor.monitor.time_to_fall import TimeToFallError, TimeToFallRegressor
from fall_predictor.monitor.records import (BALANCED, CLASS_NAMES, CONTACT_MODE_NAMES, FALLING,
                                    FEATURE_NAMES, INPUT_NAMES_WITH_ATTITUDE, N_CONTACT_MODES,
                                    N_FEATURES, N_INPUTS_WITH_ATTITUDE)

SCHEMA_NAME = 'fall_predictor.decision_lists'
SCHEMA_VERSION = 7
#: Older versions this reader still accepts (version 2: no robot mass, no time to fall;
#: version 3: decision lists only; version 4: no learned fall direction; version 5: the 15
#: features as the only inputs; version 6: per-mode time-to-fall trees only).
SUPPORTED_SCHEMA_VERSIONS = (2, 3, 4, 5, 6, 7)
#: The input vectors a model may read, by length.
INPUT_NAMES = {N_FEATURES: FEATURE_NAMES, N_INPUTS_WITH_ATTITUDE: INPUT_NAMES_WITH_ATTITUDE}
#: Values of ``training.state`` (optional; absent = 'true').
TRAINING_STATES = ('true', 'estimated')
_CLASS_BY_NAME = {CLASS_NAMES[BALANCED]: BALANCED, CLASS_NAMES[FALLING]: FALLING}

PathLike = Union[str, 'os.PathLike[str]']


class ModelFileError(TeamFileError):
    """A model file that cannot be read or is not a valid model; the message names the file."""


def _utc_now() -> str:
    return datetime.now(timezone.utc).strftime('%Y-%m-%dT%H:%M:%SZ')


@dataclass(frozen=True)
class ModelMetadata:
    """Provenance of a model: how it was trained and on what.

    ``learner_params`` must be JSON-serialisable (the learner's ``get_params()``).
    ``recommended_tau_his_s`` [s] is the history window the model was selected with, a default
    for the run-time parameter (None: no recommendation).
    """

    tau_plus_s: float
    balanced_weight: float
    falling_weight: float
    learner_name: str
    learner_params: dict[str, Any]
    dataset_fingerprint: str
    recommended_tau_his_s: Optional[float] = None
    #: Every ``sample_stride``-th 1 kHz sample was trained on, its weight multiplied by the stride.
    sample_stride: int = 1
    #: How the training features were computed; the monitor must compute them the same way.
    feature_settings: FeatureSettings = field(default_factory=FeatureSettings)
    created_utc: str = field(default_factory=_utc_now)
    package_version: str = __version__
    #: Total robot mass [kg] of the training data (None in version-2 files).
    robot_mass_kg: Optional[float] = None
    #: Seconds left until fallen: per contact mode, or boosted trees fitted from each trigger
    #: to fallen (None: the model has none).
    time_to_fall: Optional[Union[TimeToFallRegressor, BoostedTimeToFall]] = field(
        default=None, compare=False)
    #: The state the training features came from: 'true' (the simulator's) or 'estimated'
    #: (the state estimator's, from the sensor topics); files without it were trained on 'true'.
    state: str = 'true'
    #: Trained on the trajectories and their left-right mirror images.
    mirror: bool = False
    #: The learned fall direction (None: the momentum's direction).
    fall_direction: Optional[LearnedDirection] = field(default=None, compare=False)


def _classifier_document(mode_name: str, classifier: DecisionList | BoostedTrees) -> dict[str, Any]:
    if isinstance(classifier, BoostedTrees):
        return {'mode': mode_name, 'boosted_trees': classifier.to_json()}
    return {'mode': mode_name, 'default': CLASS_NAMES[classifier.default],
            'rules': [{'label': CLASS_NAMES[rule.label],
                       'conditions': [{'feature': c.feature, 'op': c.op, 'threshold': c.threshold}
                                      for c in rule.conditions]}
                      for rule in classifier.rules]}


def _model_document(lists: PerModeDecisionLists, metadata: ModelMetadata) -> dict[str, Any]:
    return {
        'schema': SCHEMA_NAME,
        'schema_version': SCHEMA_VERSION,
        'feature_names': list(FEATURE_NAMES),
        'input_names': list(INPUT_NAMES[lists.n_inputs]),
        'contact_mode_names': list(CONTACT_MODE_NAMES),
        'lists': [_classifier_document(mode_name, classifier)
                  for mode_name, classifier in zip(CONTACT_MODE_NAMES, lists.lists)],
        'features': asdict(metadata.feature_settings),
        'training': {
            'tau_plus_s': metadata.tau_plus_s,
            'balanced_weight': metadata.balanced_weight,
            'falling_weight': metadata.falling_weight,
            'sample_stride': metadata.sample_stride,
            'learner': {'name': metadata.learner_name, 'params': metadata.learner_params},
            'state': metadata.state,
            'mirror': metadata.mirror,
        },
        'recommended_tau_his_s': metadata.recommended_tau_his_s,
        'dataset_fingerprint': metadata.dataset_fingerprint,
        'created': {'utc': metadata.created_utc, 'package_version': metadata.package_version},
        'robot_mass_kg': metadata.robot_mass_kg,
        'time_to_fall': None if metadata.time_to_fall is None else metadata.time_to_fall.to_json(),
        'fall_direction': (None if metadata.fall_direction is None
                           else metadata.fall_direction.to_json()),
    }


def save_model(path: PathLike, lists: PerModeDecisionLists, metadata: ModelMetadata) -> None:
    """Write the model as JSON to ``path`` atomically (a temporary file, then a rename).

    The written file is checked by loading it back from memory before it replaces ``path``;
    metadata that would not load (a non-finite number, a non-JSON parameter) raises
    :class:`ModelFileError` and leaves ``path`` untouched.
    """
    path = Path(path)
    try:
        text = json.dumps(_model_document(lists, metadata), indent=1, allow_nan=False) + '\n'
    except (TypeError, ValueError) as error:
        raise ModelFileError(f'{path}: cannot write model: {error}') from error
    _parse_model(text, path)
    with atomic_output(path) as temporary:
        temporary.write_text(text, encoding='utf-8')


#: Largest model file read [bytes] by default: the shipped models are 0.4-1.3 MB; a file far
#: larger is not a model, and reading it would cost the node memory and start-up time.
DEFAULT_MAX_MODEL_BYTES = 20_000_000


def load_model(path: PathLike, max_bytes: int = DEFAULT_MAX_MODEL_BYTES
               ) -> tuple[PerModeDecisionLists, ModelMetadata]:
    """Read and validate a model file; raises :class:`ModelFileError` on any problem.

    Only a regular file of at most ``max_bytes`` bytes is read (a FIFO, a device or a directory
    is refused without reading, see :func:`~fall_predictor.monitor.fileio.read_regular_file`).
    """
    path = Path(path)
    try:
        text = read_regular_file(path, max_bytes).decode('utf-8')
    except OSError as error:
        raise ModelFileError(f'{path}: cannot read model file: {error}') from error
    except UnicodeDecodeError as error:
        raise ModelFileError(f'{path}: not UTF-8 text: {error}') from error
    return _parse_model(text, path)


class _Reader:
    """Typed access to a parsed JSON document with errors naming the file and the field."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, where: str, problem: str) -> ModelFileError:
        return ModelFileError(f'{self.path}: {where}: {problem}')

    def object(self, value: Any, where: str, keys: tuple[str, ...]) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(where, f'expected an object, got {type(value).__name__}')
        missing = [key for key in keys if key not in value]
        unknown = sorted(set(value) - set(keys))
        if missing:
            raise self.fail(where, f'missing key(s) {", ".join(missing)}')
        if unknown:
            raise self.fail(where, f'unknown key(s) {", ".join(unknown)}')
        return value

    def array(self, value: Any, where: str) -> list[Any]:
        if not isinstance(value, list):
            raise self.fail(where, f'expected an array, got {type(value).__name__}')
        return value

    def string(self, value: Any, where: str) -> str:
        if not isinstance(value, str):
            raise self.fail(where, f'expected a string, got {value!r}')
        return value

    def number(self, value: Any, where: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(where, f'expected a number, got {value!r}')
        if not math.isfinite(value):
            raise self.fail(where, f'non-finite number {value!r}')
        return float(value)

    def class_name(self, value: Any, where: str) -> int:
        name = self.string(value, where)
        if name not in _CLASS_BY_NAME:
            raise self.fail(where, f'unknown class {name!r}; expected one of {sorted(_CLASS_BY_NAME)}')
        return _CLASS_BY_NAME[name]


def _parse_model(text: str, path: Path) -> tuple[PerModeDecisionLists, ModelMetadata]:
    read = _Reader(path)
    try:
        document = json.loads(text)
    except json.JSONDecodeError as error:
        raise ModelFileError(f'{path}: malformed or truncated JSON: {error}') from error
    except RecursionError as error:
        raise ModelFileError(f'{path}: JSON nested too deeply') from error
    if not isinstance(document, dict):
        raise read.fail('top level', f'expected an object, got {type(document).__name__}')
    schema = document.get('schema')
    if schema != SCHEMA_NAME:
        raise read.fail('schema', f'expected {SCHEMA_NAME!r}, got {schema!r}')
    version = document.get('schema_version')
    if version not in SUPPORTED_SCHEMA_VERSIONS or isinstance(version, bool):
        raise read.fail('schema_version', f'unsupported version {version!r}; this reader supports '
                                          f'{list(SUPPORTED_SCHEMA_VERSIONS)}')
    read.object(document, 'top level', ('schema', 'schema_version', 'feature_names',
                                         'contact_mode_names', 'lists', 'features', 'training',
                                         'recommended_tau_his_s', 'dataset_fingerprint', 'created')
                + (('robot_mass_kg', 'time_to_fall') if version >= 3 else ())
                + (('fall_direction',) if version >= 5 else ())
                + (('input_names',) if version >= 6 else ()))
    mass = document.get('robot_mass_kg')
    if mass is not None:
        mass = read.number(mass, 'robot_mass_kg')
        if mass <= 0.0:
            raise read.fail('robot_mass_kg', f'must be > 0, got {mass!r}')
    time_to_fall = document.get('time_to_fall')
    if time_to_fall is not None:
        try:
            if version >= 7 and isinstance(time_to_fall, dict) and 'kind' in time_to_fall:
                time_to_fall = BoostedTimeToFall.from_json(time_to_fall)
            else:
                time_to_fall = TimeToFallRegressor.from_json(time_to_fall)
        except (TimeToFallError, BoostedTreesError) as error:
            raise read.fail('time_to_fall', str(error)) from error
    fall_direction = document.get('fall_direction')
    if fall_direction is not None:
        try:
            fall_direction = LearnedDirection.from_json(fall_direction, 'fall_direction')
        except FallDirectionError as error:
            raise read.fail('fall_direction', str(error)) from error
    if document['feature_names'] != list(FEATURE_NAMES):
        raise read.fail('feature_names', f'expected {list(FEATURE_NAMES)}, got {document["feature_names"]!r}')
    input_names = document.get('input_names', list(FEATURE_NAMES))
    n_inputs = next((n for n, names in INPUT_NAMES.items() if input_names == list(names)), None)
    if n_inputs is None:
        raise read.fail('input_names', f'expected the 15 feature names, or them followed by '
                                       f'{list(INPUT_NAMES_WITH_ATTITUDE[N_FEATURES:])}, got {input_names!r}')
    if document['contact_mode_names'] != list(CONTACT_MODE_NAMES):
        raise read.fail('contact_mode_names',
                        f'expected {list(CONTACT_MODE_NAMES)}, got {document["contact_mode_names"]!r}')

    raw_lists = read.array(document['lists'], 'lists')
    if len(raw_lists) != N_CONTACT_MODES:
        raise read.fail('lists', f'expected {N_CONTACT_MODES} lists (one per contact mode), got {len(raw_lists)}')
    lists = []
    for mode, raw_list in enumerate(raw_lists):
        where = f'lists[{mode}]'
        boosted = version >= 4 and isinstance(raw_list, dict) and 'boosted_trees' in raw_list
        raw_list = read.object(raw_list, where, ('mode', 'boosted_trees') if boosted
                               else ('mode', 'default', 'rules'))
        if raw_list['mode'] != CONTACT_MODE_NAMES[mode]:
            raise read.fail(f'{where}.mode', f'expected {CONTACT_MODE_NAMES[mode]!r}, got {raw_list["mode"]!r}')
        if boosted:
            try:
                lists.append(BoostedTrees.from_json(raw_list['boosted_trees'], n_inputs))
            except BoostedTreesError as error:
                raise read.fail(f'{where}.boosted_trees', str(error)) from error
            continue
        default = read.class_name(raw_list['default'], f'{where}.default')
        rules = []
        for r, raw_rule in enumerate(read.array(raw_list['rules'], f'{where}.rules')):
            rule_where = f'{where}.rules[{r}]'
            raw_rule = read.object(raw_rule, rule_where, ('label', 'conditions'))
            label = read.class_name(raw_rule['label'], f'{rule_where}.label')
            conditions = []
            for c, raw in enumerate(read.array(raw_rule['conditions'], f'{rule_where}.conditions')):
                condition_where = f'{rule_where}.conditions[{c}]'
                raw = read.object(raw, condition_where, ('feature', 'op', 'threshold'))
                feature = raw['feature']
                if isinstance(feature, bool) or not isinstance(feature, int) or not 0 <= feature < N_FEATURES:
                    raise read.fail(f'{condition_where}.feature',
                                    f'feature index must be an integer in [0, {N_FEATURES}), got {feature!r}')
                if raw['op'] not in COMPARISON_OPS:
                    raise read.fail(f'{condition_where}.op',
                                    f'unknown operator {raw["op"]!r}; expected one of {list(COMPARISON_OPS)}')
                threshold = read.number(raw['threshold'], f'{condition_where}.threshold')
                conditions.append(Condition(feature, raw['op'], threshold))
            rules.append(Rule(tuple(conditions), label))
        lists.append(DecisionList(tuple(rules), default))

    training = document['training']
    training = read.object(training, 'training',
                           ('tau_plus_s', 'balanced_weight', 'falling_weight', 'sample_stride', 'learner')
                           + tuple(k for k in ('state', 'mirror') if isinstance(training, dict) and k in training))
    state = read.string(training.get('state', 'true'), 'training.state')
    if state not in TRAINING_STATES:
        raise read.fail('training.state', f'expected one of {list(TRAINING_STATES)}, got {state!r}')
    mirror = training.get('mirror', False)
    if not isinstance(mirror, bool):
        raise read.fail('training.mirror', f'expected true or false, got {mirror!r}')
    learner = read.object(training['learner'], 'training.learner', ('name', 'params'))
    params = learner['params']
    if not isinstance(params, dict):
        raise read.fail('training.learner.params', f'expected an object, got {type(params).__name__}')
    weights = {}
    for key in ('balanced_weight', 'falling_weight'):
        weights[key] = read.number(training[key], f'training.{key}')
        if weights[key] <= 0.0:
            raise read.fail(f'training.{key}', f'weight must be positive, got {weights[key]!r}')
    stride = training['sample_stride']
    if isinstance(stride, bool) or not isinstance(stride, int) or stride < 1:
        raise read.fail('training.sample_stride', f'expected a positive integer, got {stride!r}')
    tau_his = document['recommended_tau_his_s']
    if tau_his is not None:
        tau_his = read.number(tau_his, 'recommended_tau_his_s')
        if tau_his < 0.0:
            raise read.fail('recommended_tau_his_s', f'must be >= 0, got {tau_his!r}')
    raw_features = read.object(document['features'], 'features', tuple(FeatureSettings.__dataclass_fields__))
    try:
        feature_settings = FeatureSettings(**{name: read.number(value, f'features.{name}')
                                              for name, value in raw_features.items()})
    except ValueError as error:
        raise read.fail('features', str(error)) from error
    created = read.object(document['created'], 'created', ('utc', 'package_version'))
    metadata = ModelMetadata(
        tau_plus_s=read.number(training['tau_plus_s'], 'training.tau_plus_s'),
        balanced_weight=weights['balanced_weight'], falling_weight=weights['falling_weight'],
        learner_name=read.string(learner['name'], 'training.learner.name'),
        learner_params=params,
        dataset_fingerprint=read.string(document['dataset_fingerprint'], 'dataset_fingerprint'),
        recommended_tau_his_s=tau_his, sample_stride=stride, feature_settings=feature_settings,
        created_utc=read.string(created['utc'], 'created.utc'),
        package_version=read.string(created['package_version'], 'created.package_version'),
        robot_mass_kg=mass, time_to_fall=time_to_fall, state=state, mirror=mirror,
        fall_direction=fall_direction)
    model = PerModeDecisionLists(tuple(lists))
    if model.n_inputs != n_inputs:
        raise read.fail('input_names', f'{len(input_names)} inputs, but no classifier reads beyond '
                                       f'the {model.n_inputs} features (write input_names with '
                                       f'the model it belongs to)')
    return model, metadata
