import json
from pathlib import Path

import pytest

from fall_predictor.monitor.decision_list import Condition, DecisionList, PerModeDecisionLists, Rule
from fall_predictor.learning.learners import TreeListLearner, learner_description
from fall_predictor.monitor.features import FeatureSettings
from fall_predictor.monitor.model_file import (SCHEMA_NAME, SCHEMA_VERSION, ModelFileError, ModelMetadata,
                                       load_model, save_model)
from fall_predictor.monitor.records import BALANCED, FALLING, N_CONTACT_MODES


def example_lists() -> PerModeDecisionLists:
    lists = [DecisionList() for _ in range(N_CONTACT_MODES)]
    lists[6] = DecisionList((
        Rule((Condition(10, '>', -64.5), Condition(12, '<=', 15.95)), FALLING),
        Rule((Condition(2, '<=', 0.35000000000000003),), FALLING),
        Rule((), BALANCED),
    ))
    lists[15] = DecisionList((Rule((), FALLING),))
    return PerModeDecisionLists(tuple(lists))


def example_metadata() -> ModelMetadata:
    learner = learner_description(TreeListLearner(max_depth=5))
    return ModelMetadata(tau_plus_s=-0.25, balanced_weight=4.0, falling_weight=1.0,
                         learner_name=learner['name'], learner_params=learner['params'],
                         dataset_fingerprint='sha256:0123abcd', recommended_tau_his_s=0.06,
                         feature_settings=FeatureSettings(rate_window_s=0.02, edge_tolerance_m=0.005,
                                                          sample_period_s=0.002,
                                                          guard_com_height_m=0.45))


@pytest.fixture
def model_path(tmp_path: Path) -> Path:
    path = tmp_path / 'model.json'
    save_model(path, example_lists(), example_metadata())
    return path


def test_round_trip_is_exact(model_path):
    lists, metadata = load_model(model_path)
    assert lists == example_lists()
    assert lists.lists[6].rules[1].conditions[0].threshold == 0.35000000000000003
    expected = example_metadata()
    assert metadata.learner_params == expected.learner_params
    assert (metadata.tau_plus_s, metadata.balanced_weight, metadata.falling_weight,
            metadata.learner_name, metadata.dataset_fingerprint, metadata.recommended_tau_his_s) == (
        -0.25, 4.0, 1.0, 'TreeListLearner', 'sha256:0123abcd', 0.06)
    assert metadata.feature_settings == FeatureSettings(0.02, 0.005, 0.002, 0.45)
    document = json.loads(model_path.read_text())
    assert document['schema'] == SCHEMA_NAME and document['schema_version'] == SCHEMA_VERSION
    assert document['lists'][6]['rules'][0]['conditions'][0] == {'feature': 10, 'op': '>', 'threshold': -64.5}
    # Saving what was loaded reproduces the file byte for byte.
    again = model_path.with_name('again.json')
    save_model(again, lists, metadata)
    assert again.read_bytes() == model_path.read_bytes()


def edit(path: Path, change) -> None:
    document = json.loads(path.read_text())
    change(document)
    path.write_text(json.dumps(document))


def set_condition(key, value):
    def change(document):
        document['lists'][6]['rules'][0]['conditions'][0][key] = value
    return change


@pytest.mark.parametrize('change, message', [
    (lambda d: d.update(schema='something.else'), 'schema'),
    (lambda d: d.update(schema_version=1), 'unsupported version 1'),
    (lambda d: d.pop('features'), 'missing key.*features'),
    (lambda d: d['features'].update(rate_window_s=-0.01), 'features'),
    (lambda d: d['features'].update(sample_period_s=0.05), 'sample_period_s <= rate_window_s'),
    (lambda d: d['features'].update(edge_tolerance_m='0.01'), 'features.edge_tolerance_m'),
    (lambda d: d['features'].update(extra=1.0), 'unknown key'),
    (lambda d: d.update(schema_version=True), 'unsupported version'),
    (lambda d: d['feature_names'].__setitem__(0, 'com_X'), 'feature_names'),
    (lambda d: d['feature_names'].pop(), 'feature_names'),
    (lambda d: d['contact_mode_names'].reverse(), 'contact_mode_names'),
    (lambda d: d['lists'].pop(), 'expected 16 lists'),
    (lambda d: d['lists'][3].update(mode='L-RIGHT'), r'lists\[3\]\.mode'),
    (set_condition('feature', 15), r'lists\[6\]\.rules\[0\]\.conditions\[0\]\.feature'),
    (set_condition('feature', -1), 'feature index'),
    (set_condition('feature', 2.0), 'feature index'),
    (set_condition('feature', True), 'feature index'),
    (set_condition('op', '>='), 'unknown operator'),
    (set_condition('threshold', 'NaN'), 'expected a number'),
    (set_condition('threshold', None), 'expected a number'),
    (lambda d: d['lists'][6]['rules'][0].update(label='fallen'), 'unknown class'),
    (lambda d: d['lists'][6].update(default='maybe'), 'unknown class'),
    (lambda d: d['lists'][6]['rules'][0].pop('label'), 'missing key'),
    (lambda d: d['lists'][6]['rules'][0].update(code='import os'), 'unknown key'),
    (lambda d: d.pop('training'), 'missing key'),
    (lambda d: d['training'].update(balanced_weight=-4.0), 'weight must be positive'),
    (lambda d: d['training']['learner'].update(params=[1, 2]), 'params'),
    (lambda d: d['training'].update(sample_stride=0), 'sample_stride'),
    (lambda d: d['training'].update(sample_stride=2.5), 'sample_stride'),
    (lambda d: d.update(recommended_tau_his_s=-0.1), 'recommended_tau_his_s'),
    (lambda d: d.update(dataset_fingerprint=7), 'dataset_fingerprint'),
    (lambda d: d.update(lists={}), 'expected an array'),
])
def test_invalid_content_is_rejected_with_file_and_field(model_path, change, message):
    edit(model_path, change)
    with pytest.raises(ModelFileError, match=message) as error:
        load_model(model_path)
    assert str(model_path) in str(error.value)


@pytest.mark.parametrize('literal', ['NaN', 'Infinity', '-Infinity', '1e999'])
def test_non_finite_threshold_is_rejected(model_path, literal):
    edit(model_path, set_condition('threshold', 123.25))
    model_path.write_text(model_path.read_text().replace('123.25', literal))
    with pytest.raises(ModelFileError, match='non-finite') as error:
        load_model(model_path)
    assert 'conditions[0].threshold' in str(error.value)


def test_truncated_and_malformed_files_are_rejected(model_path):
    text = model_path.read_text()
    model_path.write_text(text[:len(text) // 2])
    with pytest.raises(ModelFileError, match='truncated') as error:
        load_model(model_path)
    assert str(model_path) in str(error.value)
    model_path.write_text('')
    with pytest.raises(ModelFileError, match='malformed'):
        load_model(model_path)
    model_path.write_bytes(b'\xff\xfe{}')
    with pytest.raises(ModelFileError, match='UTF-8'):
        load_model(model_path)
    model_path.write_text('[1, 2, 3]')
    with pytest.raises(ModelFileError, match='expected an object'):
        load_model(model_path)
    with pytest.raises(ModelFileError, match='cannot read'):
        load_model(model_path.with_name('missing.json'))


def test_save_rejects_metadata_that_would_not_load(tmp_path):
    path = tmp_path / 'model.json'
    bad_params = ModelMetadata(tau_plus_s=0.0, balanced_weight=4.0, falling_weight=1.0,
                               learner_name='X', learner_params={'rng': object()},
                               dataset_fingerprint='')
    with pytest.raises(ModelFileError, match='cannot write'):
        save_model(path, example_lists(), bad_params)
    bad_number = ModelMetadata(tau_plus_s=float('nan'), balanced_weight=4.0, falling_weight=1.0,
                               learner_name='X', learner_params={}, dataset_fingerprint='')
    with pytest.raises(ModelFileError):
        save_model(path, example_lists(), bad_number)
    bad_weight = ModelMetadata(tau_plus_s=0.0, balanced_weight=0.0, falling_weight=1.0,
                               learner_name='X', learner_params={}, dataset_fingerprint='')
    with pytest.raises(ModelFileError, match='weight'):
        save_model(path, example_lists(), bad_weight)
    assert list(tmp_path.iterdir()) == []


def test_saved_model_is_readable_by_others(model_path):
    assert model_path.stat().st_mode & 0o044 == 0o044


# -- reading only what a model file can be ----------------------------------------------------

def test_only_regular_files_within_the_size_limit_are_read(tmp_path):
    import os
    from fall_predictor.monitor.fileio import UnsafeFileError, read_regular_file

    fifo = tmp_path / 'fifo'
    os.mkfifo(fifo)
    big = tmp_path / 'big.json'
    with open(big, 'wb') as f:          # 200 MB, sparse: it must be refused without reading
        f.truncate(200_000_000)
    for path, match in ((fifo, 'not a regular file'), (Path('/dev/zero'), 'not a regular file'),
                        (tmp_path, 'not a regular file'), (big, 'more than the limit')):
        with pytest.raises(UnsafeFileError, match=match):
            read_regular_file(path, 20_000_000)
        with pytest.raises(ModelFileError, match=match):
            load_model(path)
    small = tmp_path / 'small.txt'
    small.write_bytes(b'x' * 10)
    assert read_regular_file(small, 10) == b'x' * 10
    with pytest.raises(UnsafeFileError, match='10 bytes, more than the limit of 9'):
        read_regular_file(small, 9)


def test_boosted_trees_round_trip_beside_lists(tmp_path):
    from fall_predictor.monitor.boosted_trees import BoostedTrees
    from fall_predictor.monitor.time_to_fall import RegressionTree
    tree = RegressionTree((10, -1, -1), (20.0, 0.0, 0.0), (1, -1, -1), (2, -1, -1), (0.0, -0.5, 2.5))
    lists = list(example_lists().lists)
    lists[3] = BoostedTrees((tree, tree), bias=-1.0, decision_threshold=1.0)
    lists = PerModeDecisionLists(tuple(lists))
    path = tmp_path / 'boosted.json'
    save_model(path, lists, example_metadata())
    loaded, _ = load_model(path)
    assert loaded == lists and loaded.boosted and not example_lists().boosted
    document = json.loads(path.read_text())
    assert document['schema_version'] == SCHEMA_VERSION
    assert document['lists'][3] == {'mode': document['contact_mode_names'][3],
                                    'boosted_trees': lists.lists[3].to_json()}
    document['lists'][3]['boosted_trees']['trees'][1]['threshold'][0] = 'x'
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match=r'lists\[3\]\.boosted_trees: trees\[1\]'):
        load_model(path)
    # A version-3 file has no boosted entries (nor a learned direction).
    document['schema_version'] = 3
    del document['fall_direction'], document['input_names']
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match=r'lists\[3\]'):
        load_model(path)


def test_a_learned_fall_direction_round_trips_and_version_4_files_still_load(tmp_path):
    import dataclasses
    from fall_predictor.monitor.fall_direction import DIRECTION_INPUT_NAMES, LearnedDirection
    from fall_predictor.monitor.time_to_fall import RegressionTree
    tree = RegressionTree((5, -1, -1), (0.01, 0.0, 0.0), (1, -1, -1), (2, -1, -1), (0.0, -0.2, 0.3),
                          n_inputs=len(DIRECTION_INPUT_NAMES))
    learned = LearnedDirection((tree,), bias=0.05)
    path = tmp_path / 'model.json'
    save_model(path, example_lists(), dataclasses.replace(example_metadata(), fall_direction=learned))
    _, metadata = load_model(path)
    assert metadata.fall_direction == learned
    document = json.loads(path.read_text())
    assert document["schema_version"] == SCHEMA_VERSION == 7
    document['fall_direction']['trees'][0]['value'][1] = 'x'
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match=r'fall_direction\.trees\[0\]'):
        load_model(path)
    # Version 4 has no learned direction: the monitor then gives the momentum's.
    del document['fall_direction'], document['input_names']
    document['schema_version'] = 4
    path.write_text(json.dumps(document))
    assert load_model(path)[1].fall_direction is None


def test_a_model_reading_the_attitude_names_its_19_inputs_and_older_files_read_15(tmp_path):
    """Version 6: ``input_names`` says what the classifiers read. Trees over the 19 inputs (the
    features, then the base's attitude) round-trip with them; a file whose names and trees
    disagree, or that names other inputs, is refused; a version-5 file reads the 15 features."""
    from fall_predictor.monitor.boosted_trees import BoostedTrees
    from fall_predictor.monitor.records import FEATURE_NAMES, INPUT_NAMES_WITH_ATTITUDE
    from fall_predictor.monitor.time_to_fall import RegressionTree
    reads_angular_velocity_x = RegressionTree((17, -1, -1), (1.5, 0.0, 0.0), (1, -1, -1), (2, -1, -1),
                                     (0.0, -0.5, 2.5), n_inputs=19)
    lists = list(example_lists().lists)
    lists[3] = BoostedTrees((reads_angular_velocity_x,), bias=-1.0, decision_threshold=0.0)
    lists = PerModeDecisionLists(tuple(lists))
    assert lists.n_inputs == 19 and example_lists().n_inputs == 15
    path = tmp_path / 'attitude.json'
    save_model(path, lists, example_metadata())
    loaded, _ = load_model(path)
    assert loaded == lists and loaded.n_inputs == 19
    document = json.loads(path.read_text())
    assert document['input_names'] == list(INPUT_NAMES_WITH_ATTITUDE)
    # The same trees declared over the 15 features: input 17 is not there.
    document['input_names'] = list(FEATURE_NAMES)
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match=r'lists\[3\]\.boosted_trees.*17'):
        load_model(path)
    document['input_names'] = list(FEATURE_NAMES) + ['imu_yaw']
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match='input_names'):
        load_model(path)
    # Lists that read the 15 features, declared over 19: the names belong to another model.
    plain = tmp_path / 'plain.json'
    save_model(plain, example_lists(), example_metadata())
    document = json.loads(plain.read_text())
    document['input_names'] = list(INPUT_NAMES_WITH_ATTITUDE)
    plain.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match='input_names: 19 inputs'):
        load_model(plain)
    document['schema_version'] = 5
    del document['input_names']
    plain.write_text(json.dumps(document))
    assert load_model(plain)[0].n_inputs == 15


def test_a_boosted_time_to_fall_round_trips_and_a_version_6_file_refuses_it(tmp_path):
    """Version 7: ``time_to_fall`` may be boosted trees over the 15 features (method §8d); a
    file that says version 6 may not hold them."""
    import dataclasses
    from fall_predictor.monitor.boosted_trees import BoostedTimeToFall
    from fall_predictor.monitor.time_to_fall import RegressionTree
    # Below a CoM height of 0.45 m: 0.2 s less than the bias says.
    tree = RegressionTree((2, -1, -1), (0.45, 0.0, 0.0), (1, -1, -1), (2, -1, -1), (0.0, -0.2, 0.05))
    boosted = BoostedTimeToFall((tree, tree), bias=0.3)
    path = tmp_path / 'model.json'
    save_model(path, example_lists(), dataclasses.replace(example_metadata(), time_to_fall=boosted))
    _, metadata = load_model(path)
    assert metadata.time_to_fall == boosted
    x = [0.0] * 15
    x[2] = 0.40
    assert metadata.time_to_fall.predict_one(x, 3) == 0.0          # 0.3 - 0.4, never negative
    x[2] = 0.55
    assert metadata.time_to_fall.predict_one(x, 3) == pytest.approx(0.4)
    document = json.loads(path.read_text())
    assert document['time_to_fall']['kind'] == 'boosted'
    document['schema_version'] = 6
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match='time_to_fall'):
        load_model(path)
    document['schema_version'] = 7
    document['time_to_fall']['kind'] = 'other'
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match='time_to_fall.*kind'):
        load_model(path)
