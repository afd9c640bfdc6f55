"""``generate --causes``: a small mixed dataset of the G1 under its policy in MuJoCo, its index's
causes, parameters and onsets, its push runs bit for bit those of a push-only dataset, and
``stats`` per cause."""
import hashlib
import json

import pytest

from fall_predictor.cli.main import main
from fall_predictor.data.dataset import read_index
from fall_predictor.data.disturbance_generation import parse_causes, run_cause
from fall_predictor.data.generation import GenerationConfig, generate_dataset
from fall_predictor.profiles.profile import load_profile
from fall_predictor.sim.pushes import PushDistribution

MIX = parse_causes('push:0.3,trip,slip,step,fault,walk')
SEED = 4


def _config(causes):
    return GenerationConfig(seed=SEED, horizon_after_push_s=0.5, settle_extension_s=0.0, pre_push_s=0.3,
                            robot='g1_12dof', controller='unitree_rl_gym', sensor_noise_scale=1.0,
                            causes=causes, walk_s=3.0)


def _bag_digest(out, row) -> str:
    h = hashlib.sha256()
    for f in sorted((out / row.bag).iterdir()):
        h.update(f.name.encode() + f.read_bytes())
    return h.hexdigest()


@pytest.fixture(scope='module')
def mixed(tmp_path_factory):
    out = tmp_path_factory.mktemp('mixed')
    rows = generate_dataset(out, 6, SEED, config=_config(MIX), progress=False)
    return out, rows


def test_each_run_records_its_cause_parameters_and_measured_onset(mixed):
    out, rows = mixed
    assert [r.cause for r in rows] == [run_cause(MIX, SEED, i) for i in range(6)]
    assert len({r.cause for r in rows}) >= 3
    manifest = json.loads((out / 'dataset.json').read_text())
    assert manifest['causes'] == dict(MIX) and manifest['walk_s'] == 3.0
    for row in rows:
        if row.cause == 'push':
            assert row.force_n > 0 and row.onset_s == row.t_push == row.t_onset
            continue
        assert row.force_n == 0.0 and row.params
        if row.cause == 'walk':
            assert row.t_onset is None and row.t_end == pytest.approx(3.0)
            assert row.params['times_s'][0] == 0.0
        else:
            # Measured in the run, and the recording holds the pre-onset window.
            assert row.t_onset is not None and row.t_push == row.t_onset
            assert row.t_start == pytest.approx(row.t_onset - 0.3, abs=1e-6)
        if row.cause == 'fault':
            assert row.t_onset == pytest.approx(row.params['t_start_s'], abs=0.0025)
    assert read_index(out) == rows                                 # the index reads back


def test_the_push_runs_of_a_mixed_dataset_are_those_of_a_push_only_one(mixed, tmp_path):
    out, rows = mixed
    pushes = [r for r in rows if r.cause == 'push']
    assert pushes, 'the seed draws no push in the mixed dataset: choose another'
    last = max(int(r.trajectory_id.split('_')[1]) for r in pushes)
    only = generate_dataset(tmp_path / 'pushes', last + 1, SEED, config=_config(None), progress=False)
    by_id = {r.trajectory_id: r for r in only}
    for row in pushes:
        twin = by_id[row.trajectory_id]
        assert _bag_digest(out, row) == _bag_digest(tmp_path / 'pushes', twin)
        assert (row.force_n, row.t_push, row.fallen, row.t_fallen) == (twin.force_n, twin.t_push, twin.fallen,
                                                                       twin.t_fallen)
        assert twin.cause == 'push' and twin.t_onset is None and twin.onset_s == twin.t_push


def test_generate_with_causes_and_stats_per_cause(tmp_path, capsys):
    out = tmp_path / 'cli'
    assert main(['generate', '--robot', 'g1_12dof', '--trajectories', '2', '--seed', '1', '--out', str(out),
                 '--horizon', '0.5', '--settle-extension', '0', '--causes', 'trip:1,fault:1', '--json']) == 0
    generated = json.loads(capsys.readouterr().out)
    assert sum(c['runs'] for c in generated['by_cause'].values()) == 2
    assert set(generated['by_cause']) <= {'trip', 'fault'}
    assert main(['stats', str(out), '--json']) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats['by_cause'] == generated['by_cause']
    assert main(['generate', '--trajectories', '1', '--out', str(tmp_path / 'bad'), '--causes', 'push,jump']) == 2
    assert 'unknown cause' in capsys.readouterr().err


def test_generate_randomize_records_each_runs_world_and_repeats_it(tmp_path, capsys):
    from fall_predictor.sim.randomization import RandomizationRanges, WorldRandomization
    args = ['generate', '--robot', 'g1_12dof', '--trajectories', '2', '--seed', '2', '--horizon', '0.5',
            '--settle-extension', '0', '--causes', 'push,fault', '--randomize', '--json']
    assert main(args + ['--out', str(tmp_path / 'a')]) == 0
    assert main(args + ['--out', str(tmp_path / 'b')]) == 0
    capsys.readouterr()
    a, b = read_index(tmp_path / 'a'), read_index(tmp_path / 'b')
    assert a == b
    ranges = RandomizationRanges().to_dict()
    for row in a:
        world = WorldRandomization(**json.loads(row.randomization))
        for name, (low, high) in ranges.items():
            assert low <= getattr(world, name) <= high
    assert json.loads((tmp_path / 'a' / 'dataset.json').read_text())['randomization'] == ranges


def test_render_a_cause_frames_the_run_around_its_measured_onset(tmp_path, capsys):
    out = tmp_path / 'trip.png'
    assert main(['render', '--robot', 'g1_12dof', '--cause', 'trip', '--seed', '2', '--frames', '2',
                 '--before', '0.2', '--after', '0.3', '--out', str(out), '--json']) == 0
    rendered = json.loads(capsys.readouterr().out)
    assert out.stat().st_size > 10_000 and rendered['frames'] == 2
    assert rendered['cause'] == 'trip' and rendered['cause_params']['height_m'] > 0
    assert 1.0 < rendered['t_onset'] < 4.0                # the first contact, measured in a first run


def test_c_bal_pushes_after_a_run_of_another_cause_are_those_of_a_push_only_dataset(tmp_path):
    """C_bal's pushes start from snapshots of one walk simulated once per worker (WalkPrefix). A
    trip run between them lays its box in the worker's world and starts it again: the snapshots
    must survive it (PyBullet refused to restore them: "Couldn't restore state") and the push runs
    be bit for bit those of a push-only dataset."""
    seed = 6                                     # runs 0-2: push, trip, push
    causes = parse_causes('push,trip')
    assert [run_cause(causes, seed, i) for i in range(3)] == ['push', 'trip', 'push']

    pushes = PushDistribution.for_robot(load_profile('g1'))

    def config(c):                               # as generate --robot g1 makes it (its fixed gait)
        return GenerationConfig(seed=seed, horizon_after_push_s=0.5, settle_extension_s=0.0,
                                pre_push_s=0.3, robot='g1', push_distribution=pushes,
                                gait_variety=False, causes=c)
    rows = generate_dataset(tmp_path / 'mixed', 3, seed, config=config(causes), progress=False)
    only = generate_dataset(tmp_path / 'pushes', 3, seed, config=config(None), progress=False)
    assert [r.cause for r in rows] == ['push', 'trip', 'push']
    for row, twin in zip(rows[::2], only[::2]):
        assert _bag_digest(tmp_path / 'mixed', row) == _bag_digest(tmp_path / 'pushes', twin)
        assert (row.force_n, row.t_push, row.fallen) == (twin.force_n, twin.t_push, twin.fallen)


def test_a_run_that_falls_before_its_disturbance_is_an_undisturbed_walk_that_fell():
    """On a randomised world the policy may fall before its disturbance acts (run 76 of seed 5713:
    a fault meant to start after the robot was down). Its recording had nothing after the
    onset ("generator raised StopIteration"); it is an undisturbed walk that fell, recorded from
    its start, the disturbance it was meant to have kept in its parameters."""
    from fall_predictor.data.generation import simulate_one
    config = GenerationConfig(seed=5713, robot='g1_12dof', controller='unitree_rl_gym',
                              sensor_noise_scale=1.0, randomize=True,
                              causes=parse_causes('push:0.2,trip:0.2,slip:0.2,step:0.2,fault:0.2'),
                              push_distribution=PushDistribution.for_robot(load_profile('g1_12dof')))
    assert run_cause(config.causes, 5713, 76) == 'fault'
    row = simulate_one(config, 76).row
    assert row.cause == 'walk' and row.t_onset is None and row.fallen
    assert row.params['fell_before_onset_of'] == 'fault'
    assert row.t_fallen < row.params['t_start_s']            # down before the fault began
    assert row.t_start == 0.0 and row.force_n == 0.0 and row.t_push == 0.0


def test_a_long_walk_is_not_reported_as_a_run_still_moving_at_the_horizon(tmp_path, capsys):
    """A walk lasts as long as asked (``--walk-s``), far past the push horizon: it has none."""
    assert main(['generate', '--robot', 'g1_12dof', '--trajectories', '1', '--seed', '3', '--out',
                 str(tmp_path / 'walk'), '--horizon', '0.5', '--settle-extension', '0', '--causes', 'walk',
                 '--walk-s', '4', '--json']) == 0
    generated = json.loads(capsys.readouterr().out)
    (row,) = read_index(tmp_path / 'walk')
    assert row.cause == 'walk' and row.t_end - row.t_force_end > 0.5 + 1.0
    assert generated['recorded_past_horizon'] == {}
