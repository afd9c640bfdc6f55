"""rosbag2/MCAP bags: exact round trips, ros2-bag-compatible metadata, damage always reported."""
import os

import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import StoragePlugin
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from fall_predictor.contract.topics import (CONTROLLER_MODE, FEATURES, JOINT_COMMANDS, JOINT_STATES,
                                            MEASUREMENT, MEASUREMENT_LABEL, PUSH, STATE)
from fall_predictor.contract.messages import measurement_msg
from fall_predictor.contract.wire import pack_measurement
from fall_predictor.data.bag_writer import BagWriter
from fall_predictor.data.bagio import (LEGACY_ARRAY_TYPE, MAX_TRAILING_BYTES, BagError, decode,
                                       deserialize_cdr, iter_messages, read_trajectory,
                                       recorded_typestore, typestore)
from fall_predictor.monitor.fall_monitor import STATUS_OK, MonitorState
from random_records import make_measurement

N_SAMPLES = 300
JOINTS = ('l_hip_yaw', 'l_knee_pitch', 'r_hip_yaw', 'r_knee_pitch')



def trajectory(seed=0):
    """N_SAMPLES measurements at 1 kHz with contact counts varying between 0 and 8 per foot."""
    rng = np.random.default_rng(seed)
    return [make_measurement(rng, *rng.integers(0, 9, 2), t=k / 1000.0)
            for k in range(N_SAMPLES)]


def write_bag(path, measurements, *, compress=True, extras=True):
    with BagWriter(path, compress=compress) as writer:
        for k, m in enumerate(measurements):
            writer.write_measurement(m)
            if extras and k % 10 == 0:
                writer.write_joint_state(m.t, JOINTS, np.full(4, k * 0.01), np.ones(4))
                writer.write_features(m.t, (np.arange(15.0) + k) * 1e-3, k % 16)
                writer.write_state(m.t, MonitorState(STATUS_OK, '', k >= 200, k >= 200, k >= 150,
                                                     False, k % 16, tau_his_s=0.044))
        if extras:
            writer.write_push(0.1, [250.0, -30.0, 0.0])
    return path


def mcap_file(bag):
    [name] = [f for f in os.listdir(bag) if f.endswith('.mcap')]
    return bag / name


@pytest.fixture(scope='module')
def measurements():
    return trajectory()


@pytest.fixture(scope='module')
def bag(tmp_path_factory, measurements):
    return write_bag(tmp_path_factory.mktemp('bags') / 'run', measurements)


def test_round_trip_is_exact(bag, measurements):
    rec = read_trajectory(bag)
    assert len(rec.measurements) == N_SAMPLES
    for got, want in zip(rec.measurements, measurements, strict=True):
        assert pack_measurement(got).tobytes() == pack_measurement(want).tobytes()
        assert got.left_contacts.shape == want.left_contacts.shape
        assert got.non_foot_contact is want.non_foot_contact
    counts = {(len(m.left_contacts), len(m.right_contacts)) for m in rec.measurements}
    assert len(counts) > 30 and any(0 in c for c in counts) and max(map(max, counts)) == 8

    js = rec.joint_states
    assert js.names == JOINTS and js.position.shape == (30, 4) and js.effort.shape == (30, 0)
    assert np.array_equal(js.t, [k / 1000.0 for k in range(0, N_SAMPLES, 10)])
    assert np.array_equal(js.position[:, 0], [k * 0.01 for k in range(0, N_SAMPLES, 10)])
    assert [p.t for p in rec.pushes] == [0.1]
    assert np.array_equal(rec.pushes[0].force, [250.0, -30.0, 0.0])
    assert [f.mode for f in rec.features] == [k % 16 for k in range(0, N_SAMPLES, 10)]
    assert [s.state.falling for s in rec.states] == [k >= 200 for k in range(0, N_SAMPLES, 10)]
    assert [s.t for s in rec.states] == [k / 1000.0 for k in range(0, N_SAMPLES, 10)]
    assert set(rec.topics) == {MEASUREMENT.name, JOINT_STATES.name, FEATURES.name, STATE.name,
                               PUSH.name}


def test_metadata_is_what_ros2_bag_needs(bag):
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['storage_identifier'] == 'mcap'
    assert info['version'] == 9                      # ROS 2 Jazzy's rosbag2 metadata version
    assert info['relative_file_paths'] == [mcap_file(bag).name]
    assert info['compression_mode'] == ''            # compression lives inside the MCAP chunks
    topics = {t['topic_metadata']['name']: t for t in info['topics_with_message_count']}
    assert topics[MEASUREMENT.name]['message_count'] == N_SAMPLES
    meta = topics[MEASUREMENT.name]['topic_metadata']
    assert meta['type'] == 'fall_predictor/msg/Measurement'
    assert meta['serialization_format'] == 'cdr'
    assert meta['type_description_hash'].startswith('RIHS01_')
    qos = meta['offered_qos_profiles'][0]
    assert (qos['reliability'], qos['durability'], qos['depth']) == ('reliable', 'volatile', 1000)
    assert info['starting_time']['nanoseconds_since_epoch'] == 0          # log time = sim time
    assert info['duration']['nanoseconds'] == (N_SAMPLES - 1) * 1_000_000


def test_mcap_chunks_are_zstd_with_checksum(bag):
    data = mcap_file(bag).read_bytes()
    assert data.startswith(b'\x89MCAP0\r\n') and data.endswith(b'\x89MCAP0\r\n')
    frame = data.index(b'\x28\xb5\x2f\xfd')          # zstd frame magic
    assert data[frame + 4] & 0b100                   # Content_Checksum_flag


def test_compression_shrinks_the_bag(tmp_path, measurements):
    plain = write_bag(tmp_path / 'plain', measurements, compress=False, extras=False)
    packed = write_bag(tmp_path / 'packed', measurements, compress=True, extras=False)
    assert mcap_file(packed).stat().st_size < 0.8 * mcap_file(plain).stat().st_size
    assert len(read_trajectory(plain).measurements) == N_SAMPLES


def test_iter_messages_filters_and_orders(bag):
    messages = list(iter_messages(bag, topics=[PUSH.name, STATE.name]))
    assert {m.topic for m in messages} == {PUSH.name, STATE.name}
    assert [m.t_ns for m in messages] == sorted(m.t_ns for m in messages)
    push = next(m for m in messages if m.topic == PUSH.name)
    assert push.t_ns == 100_000_000 and decode(push).t == 0.1


def test_generic_write_with_latched_qos(tmp_path, measurements):
    bag = tmp_path / 'modes'
    string = typestore().types['std_msgs/msg/String']
    with BagWriter(bag) as writer:
        writer.write_measurement(measurements[0])
        writer.write(CONTROLLER_MODE.name, CONTROLLER_MODE.msg_type, 0, string(data='balance'))
        writer.write_joint_state(0.0, JOINTS, np.zeros(4), topic=JOINT_COMMANDS.name)
        with pytest.raises(BagError, match='has type std_msgs/msg/String, not'):
            writer.write(CONTROLLER_MODE.name, 'std_msgs/msg/Bool', 0, None)
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    topics = {t['topic_metadata']['name']: t['topic_metadata']
              for t in info['topics_with_message_count']}
    assert topics[CONTROLLER_MODE.name]['offered_qos_profiles'][0]['durability'] == \
        'transient_local'
    [mode] = list(iter_messages(bag, topics=[CONTROLLER_MODE.name]))
    assert mode.msg.data == 'balance'


# ---------------------------------------------------------------------------- damage

@pytest.fixture
def damaged(tmp_path, bag):
    """A fresh copy of the module bag, to be damaged by the test."""
    copy = tmp_path / 'copy'
    copy.mkdir()
    for f in bag.iterdir():
        (copy / f.name).write_bytes(f.read_bytes())
    return copy


@pytest.mark.parametrize('fraction', [0.0, 0.001, 0.01, 0.25, 0.5, 0.9, 0.999])
def test_truncated_bag_raises_bag_error(damaged, fraction):
    mcap = mcap_file(damaged)
    data = mcap.read_bytes()
    mcap.write_bytes(data[:int(len(data) * fraction)])
    with pytest.raises(BagError, match=str(damaged)):
        read_trajectory(damaged)


def test_bag_cut_just_before_its_end_raises_bag_error(damaged):
    mcap = mcap_file(damaged)
    mcap.write_bytes(mcap.read_bytes()[:-1])
    with pytest.raises(BagError, match='truncated or corrupt'):
        read_trajectory(damaged)


def test_garbage_file_raises_bag_error(damaged):
    mcap = mcap_file(damaged)
    mcap.write_bytes(np.random.default_rng(1).bytes(mcap.stat().st_size))
    with pytest.raises(BagError, match=f'{damaged}.*magic is invalid'):
        read_trajectory(damaged)


@pytest.mark.parametrize('where', [0.2, 0.5, 0.8])
def test_garbage_inside_a_chunk_raises_bag_error(damaged, where):
    mcap = mcap_file(damaged)
    data = bytearray(mcap.read_bytes())
    frame = data.index(b'\x28\xb5\x2f\xfd')
    at = frame + 16 + int(where * 0.5 * (len(data) - frame))
    data[at:at + 8] = b'\xa5' * 8
    mcap.write_bytes(bytes(data))
    with pytest.raises(BagError, match=f'{damaged}: damaged bag'):    # the zstd checksum
        read_trajectory(damaged)


def test_missing_or_broken_metadata_raises_bag_error(damaged):
    meta = damaged / 'metadata.yaml'
    text = meta.read_text()
    meta.write_text(text[:len(text) // 2])
    with pytest.raises(BagError, match=f'{damaged}.*YAML'):
        read_trajectory(damaged)
    meta.unlink()
    with pytest.raises(BagError, match='metadata'):
        read_trajectory(damaged)


def test_missing_bag_raises_bag_error(tmp_path):
    with pytest.raises(BagError, match='does not exist'):
        read_trajectory(tmp_path / 'nowhere')
    with pytest.raises(BagError, match='does not exist'):
        list(iter_messages(tmp_path / 'nowhere'))


def test_bag_without_measurements_is_reported(tmp_path):
    bag = tmp_path / 'pushes_only'
    with BagWriter(bag) as writer:
        writer.write_push(0.5, [100.0, 0.0, 0.0])
    with pytest.raises(BagError, match=f'{bag}: required topic {MEASUREMENT.name} is missing'):
        read_trajectory(bag)
    rec = read_trajectory(bag, required=())
    assert rec.measurements is None and rec.joint_states is None and rec.features is None
    assert len(rec.pushes) == 1


def _legacy_measurement(values: np.ndarray, label: str = MEASUREMENT_LABEL):
    types = typestore().types
    dim = types['std_msgs/msg/MultiArrayDimension'](label=label, size=len(values), stride=len(values))
    return types['std_msgs/msg/Float64MultiArray'](
        layout=types['std_msgs/msg/MultiArrayLayout'](dim=[dim], data_offset=0), data=values)


def write_legacy_bag(bag, stamped_arrays) -> None:
    """A bag as this package wrote them before the typed messages: Float64MultiArray layouts."""
    store = typestore()
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection(MEASUREMENT.name, LEGACY_ARRAY_TYPE, typestore=store)
        for t_ns, msg in stamped_arrays:
            writer.write(conn, t_ns, store.serialize_cdr(msg, LEGACY_ARRAY_TYPE))


def test_bags_recorded_before_the_typed_messages_still_import(tmp_path, measurements):
    bag = tmp_path / 'legacy'
    write_legacy_bag(bag, [(round(m.t * 1e9), _legacy_measurement(pack_measurement(m)))
                           for m in measurements[:20]])
    rec = read_trajectory(bag)
    assert rec.topics == {MEASUREMENT.name: LEGACY_ARRAY_TYPE}
    for got, want in zip(rec.measurements, measurements[:20], strict=True):
        assert pack_measurement(got).tobytes() == pack_measurement(want).tobytes()


#: ``fall_predictor/msg/Features`` as bags recorded it before it carried the base's attitude.
FEATURES_BEFORE_ATTITUDE = """std_msgs/Header header
string fault
float64[15] features
uint8 contact_mode
float64 base_tilt
"""


def features_before_attitude(k):
    return np.arange(15.0) * 1e-3 + k * 1e-4


def write_features_before_attitude(bag, n):
    """A bag of ``n`` features messages at 1 kHz in the message's earlier definition, as the
    recorder wrote them then (the definition stored with the topic)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(FEATURES_BEFORE_ATTITUDE, FEATURES.msg_type))
    Features, Header, Time = (store.types[name] for name in (
        FEATURES.msg_type, 'std_msgs/msg/Header', 'builtin_interfaces/msg/Time'))
    writer = Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    conn = writer.add_connection(FEATURES.name, FEATURES.msg_type, typestore=store)
    for k in range(n):
        msg = Features(header=Header(stamp=Time(sec=0, nanosec=k * 1_000_000), frame_id='cop'),
                       fault='', features=features_before_attitude(k), contact_mode=k % 16,
                       base_tilt=0.01)
        writer.write(conn, k * 1_000_000, store.serialize_cdr(msg, FEATURES.msg_type))
    writer.close()


def assert_features_before_attitude(features, n):
    assert len(features) == n
    for k, sample in enumerate(features):
        np.testing.assert_array_equal(sample.x[:15], features_before_attitude(k))
        assert np.isnan(sample.x[15:]).all() and sample.x.shape == (19,)
        assert sample.mode == k % 16 and sample.t == k * 1_000_000 / 1e9


def test_a_bag_recorded_with_an_earlier_features_definition_decodes_with_it(tmp_path):
    bag = tmp_path / 'before_attitude'
    write_features_before_attitude(bag, 50)
    # The package's current definition does not read these bytes (4 values short) ...
    with Reader(bag) as reader:
        _, _, raw = next(reader.messages())
    with pytest.raises(SerdeError):
        deserialize_cdr(raw, FEATURES.msg_type)
    # ... the bag's own does: the 15 features as recorded, the attitude absent (NaN).
    rec = read_trajectory(bag, required=(FEATURES.name,))
    assert_features_before_attitude(rec.features, 50)
    # A recorded definition equal to the package's decodes with the package's own store.
    own = typestore()
    assert recorded_typestore(FEATURES.msg_type,
                              own.generate_msgdef(FEATURES.msg_type)[0]) is own
    with pytest.raises(BagError, match='does not parse'):
        recorded_typestore(FEATURES.msg_type, 'float64[ x\n')


def test_malformed_message_in_bag_is_reported(tmp_path, measurements):
    bag = tmp_path / 'bad_label'
    write_legacy_bag(bag, [(0, _legacy_measurement(pack_measurement(measurements[0]))),
                           (5_000_000, _legacy_measurement(np.zeros(26), 'other/v1'))])
    with pytest.raises(BagError, match=f"malformed {MEASUREMENT.name} message at 5000000 ns: "
                                       "layout label 'other/v1'"):
        read_trajectory(bag)
    typed = tmp_path / 'nan_com'
    with BagWriter(typed) as writer:
        writer.write_measurement(measurements[0])
        bad = measurement_msg(writer._types, 5_000_000, 'odom', measurements[1])
        bad.com.x = float('nan')
        writer.write(MEASUREMENT.name, MEASUREMENT.msg_type, 5_000_000, bad)
    with pytest.raises(BagError, match=f'malformed {MEASUREMENT.name} message at 5000000 ns: '
                                       'measurement has non-finite values'):
        read_trajectory(typed)


def test_known_topic_with_wrong_type_is_reported(tmp_path):
    bag = tmp_path / 'wrong_type'
    store = typestore()
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection(MEASUREMENT.name, 'std_msgs/msg/String', typestore=store)
        writer.write(conn, 0, store.serialize_cdr(store.types['std_msgs/msg/String']('x'),
                                                  'std_msgs/msg/String'))
    with pytest.raises(BagError, match='has type std_msgs/msg/String, expected'):
        read_trajectory(bag)


def test_changing_joint_names_are_reported(tmp_path, measurements):
    bag = tmp_path / 'joints'
    with BagWriter(bag) as writer:
        writer.write_measurement(measurements[0])
        writer.write_joint_state(0.0, ('a', 'b'), [0.0, 0.0])
        writer.write_joint_state(0.01, ('a', 'c'), [0.0, 0.0])
    with pytest.raises(BagError, match=r'joint names change at t=0\.01'):
        read_trajectory(bag)


def test_writer_refuses_existing_path_and_aborts_on_error(tmp_path, measurements):
    with pytest.raises(BagError, match=r'cannot create bag.*exists'), BagWriter(tmp_path):
        pass
    bag = tmp_path / 'aborted'
    with pytest.raises(RuntimeError), BagWriter(bag) as writer:
        writer.write_measurement(measurements[0])
        raise RuntimeError('simulation crashed')
    assert not (bag / 'metadata.yaml').exists()
    with pytest.raises(BagError, match='metadata'):
        read_trajectory(bag)


def _joint_state_as_dds_sends_it(position, velocity, effort, names=('knee', 'hip')) -> bytes:
    """A ``sensor_msgs/JointState`` serialized by rclpy (rmw_fastrtps), as a robot's driver
    publishes it and ``ros2 bag`` records it."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    msg = JointState(name=list(names), position=position, velocity=velocity, effort=effort)
    msg.header.stamp.sec, msg.header.stamp.nanosec = 1_795_852_800, 5_000_000
    return serialize_message(msg)


@pytest.mark.parametrize('velocity, effort, unwritten', [([0.1, 0.0], [], 4), ([], [], 8),
                                                        ([0.1, 0.0], [12.0, -3.5], 0)])
def test_joint_states_without_efforts_as_fast_dds_sends_them_decode(velocity, effort, unwritten):
    raw = _joint_state_as_dds_sends_it([0.3, -0.1], velocity, effort)
    msg = deserialize_cdr(raw, JOINT_STATES.msg_type)
    assert list(msg.name) == ['knee', 'hip'] and msg.position.tolist() == [0.3, -0.1]
    assert msg.velocity.tolist() == velocity and msg.effort.tolist() == effort
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1_795_852_800, 5_000_000)
    # The bytes after the last member, counted against an independent serializer (rosbags' own,
    # which writes none): more than the 3 rosbags reads when the arrays end empty.
    assert len(raw) - len(typestore().serialize_cdr(msg, JOINT_STATES.msg_type)) == unwritten


def test_more_bytes_after_a_message_or_a_cut_message_is_refused():
    from rosbags.serde import SerdeError
    raw = _joint_state_as_dds_sends_it([0.3, -0.1], [0.1, 0.0], [12.0, -3.5])     # none after it
    deserialize_cdr(raw + bytes(MAX_TRAILING_BYTES), JOINT_STATES.msg_type)
    with pytest.raises(SerdeError, match='bytes after its last member'):
        deserialize_cdr(raw + bytes(MAX_TRAILING_BYTES + 1), JOINT_STATES.msg_type)
    with pytest.raises(SerdeError):
        deserialize_cdr(raw[:30], JOINT_STATES.msg_type)
    with pytest.raises(SerdeError, match='encapsulation'):
        deserialize_cdr(b'\x07\x07' + raw[2:], JOINT_STATES.msg_type)


def test_a_robot_bag_of_joint_states_without_efforts_reads(tmp_path, measurements):
    """A robot that measures no joint efforts: its recorded ``/joint_states`` read back."""
    bag = tmp_path / 'robot'
    with BagWriter(bag) as writer:
        writer.write_measurement(measurements[0])
        for k in range(3):
            writer.write_raw(JOINT_STATES.name, JOINT_STATES.msg_type, k * 10_000_000,
                             _joint_state_as_dds_sends_it([0.1 * k, 0.0], [0.0, 0.0], []))
    read = [m.msg for m in iter_messages(bag, [JOINT_STATES.name])]
    assert [m.position[0] for m in read] == [0.0, 0.1, 0.2] and all(len(m.effort) == 0 for m in read)


def test_split_joint_states_read_as_one_row_per_stamp(tmp_path, measurements):
    """A robot whose legs' driver publishes at 1 kHz and the upper body's at 500 Hz, the upper
    body without velocities: one row per stamp, each group in its own columns, NaN where a group
    sent nothing."""
    bag = tmp_path / 'split'
    legs, upper = ('l_knee', 'r_knee'), ('waist', 'neck', 'arm')
    with BagWriter(bag) as writer:
        writer.write_measurement(measurements[0])
        for k in range(6):
            t = k / 1000.0
            writer.write_joint_state(t, legs, [k, -k], [10.0 * k, -10.0 * k])
            if k % 2 == 0:
                writer.write_joint_state(t, upper, [0.5 * k, 1.0, 2.0])
    js = read_trajectory(bag).joint_states
    assert js.names == legs + upper
    np.testing.assert_array_equal(js.t, [k / 1000.0 for k in range(6)])
    np.testing.assert_array_equal(js.position[:, :2], [[k, -k] for k in range(6)])
    np.testing.assert_array_equal(js.position[::2, 2], [0.0, 1.0, 2.0])
    assert np.isnan(js.position[1::2, 2:]).all()
    np.testing.assert_array_equal(js.velocity[:, 1], [-10.0 * k for k in range(6)])
    assert np.isnan(js.velocity[:, 2:]).all() and js.effort.shape == (6, 0)


def test_split_joint_states_that_overlap_or_repeat_are_refused(tmp_path, measurements):
    bag = tmp_path / 'twice'
    with BagWriter(bag) as writer:
        writer.write_measurement(measurements[0])
        writer.write_joint_state(0.0, ('a', 'b'), [0.0, 0.0])
        writer.write_joint_state(0.0, ('c',), [0.0])
        writer.write_joint_state(0.0, ('c',), [1.0])
    with pytest.raises(BagError, match=r'two messages of the same joints at t=0\.0'):
        read_trajectory(bag)


def test_a_joint_named_twice_in_one_message_is_refused(tmp_path, measurements):
    bag = tmp_path / 'twice_named'
    with BagWriter(bag) as writer:
        writer.write_measurement(measurements[0])
        # The writer refuses such a message (WireFormatError); another recorder may not.
        types = typestore().types
        msg = types[JOINT_STATES.msg_type](
            header=types['std_msgs/msg/Header'](
                stamp=types['builtin_interfaces/msg/Time'](sec=0, nanosec=2_000_000), frame_id=''),
            name=['a', 'a'], position=np.array([0.0, 1.0]), velocity=np.zeros(0),
            effort=np.zeros(0))
        writer.write(JOINT_STATES.name, JOINT_STATES.msg_type, 2_000_000, msg)
    with pytest.raises(BagError, match=r'at 2000000 ns: joint state names are not unique'):
        read_trajectory(bag)
