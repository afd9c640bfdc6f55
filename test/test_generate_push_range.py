"""``fall-predictor generate --push-force-n LOW,HIGH``: a second sampler of the same robot, its pushes
drawn from another force range than its profile's (method §11, "A budget that holds")."""
import json

import pytest

from fall_predictor.cli import build_parser, main
from fall_predictor.data.dataset import read_index
from fall_predictor.sim.pushes import trajectory_seed

SHORT = ['--horizon', '0.2', '--settle-extension', '0', '--json']


def _config(argv):
    from fall_predictor.cli.dataset import generation_config
    return generation_config(build_parser().parse_args(['generate', '--trajectories', '2', '--out', 'x']
                                                       + argv))


def _drawn(config) -> dict:
    """The manifest's push distribution as dataset.json holds it."""
    return json.loads(json.dumps(config.manifest()))['push_distribution']


def _push(config, index):
    """Run ``index``'s push as the generator draws it (C_bal: gait then push; a policy: command
    then push)."""
    from fall_predictor.sim.policy_runs import commanded_pushes
    rng = trajectory_seed(config.seed, index)
    if config.policy is not None:
        return commanded_pushes(config.policy).sample(rng)[1]
    return config.pushes.sample_with_gait(rng)[1]


@pytest.mark.parametrize('robot, profile_range', [
    ('asimo_like', [0.0, 500.0]),       # C_bal, PyBullet: the default robot (method §3's range)
    ('g1', [0.0, 200.0]),               # C_bal, PyBullet: a robot with a range of its own
    ('g1_12dof', [0.0, 1000.0]),        # a learned policy in MuJoCo: controllers.<name>.push_force_n
])
def test_the_range_replaces_the_profiles_and_is_what_the_manifest_records(robot, profile_range):
    own = _config(['--robot', robot])
    assert _drawn(own)['force_n'] == profile_range
    other = _config(['--robot', robot, '--push-force-n', '150,300'])
    assert _drawn(other)['force_n'] == [150.0, 300.0]
    # The rest of the manifest (directions, onsets, gaits or commands, the robot) is the profile's.
    assert {k: v for k, v in _drawn(other).items() if k != 'force_n'} == \
           {k: v for k, v in _drawn(own).items() if k != 'force_n'}
    forces = []
    for index in range(300):
        a, b = _push(own, index), _push(other, index)
        # One uniform draw either way: the same run but for its force, U[150, 300] instead.
        assert (b.angle_deg, b.height_m, b.t_push) == (a.angle_deg, a.height_m, a.t_push)
        lo, hi = profile_range
        assert b.force_n == pytest.approx(150.0 + (a.force_n - lo) / (hi - lo) * 150.0)
        forces.append(b.force_n)
    assert 150.0 <= min(forces) < 155.0 and 295.0 < max(forces) <= 300.0


@pytest.mark.parametrize('robot', [
    ['--fixed-gait'],                   # C_bal in PyBullet, its walk simulated once per worker
    ['--robot', 'g1_12dof'],            # a learned policy in MuJoCo, its profile read by each worker
])
def test_two_worker_processes_push_every_run_at_the_range_and_a_resume_keeps_it(robot, tmp_path, capsys):
    out = tmp_path / 'd'
    argv = ['generate', '--trajectories', '2', '--seed', '0', '--jobs', '2', '--out', str(out)] + robot + SHORT
    assert main(argv + ['--push-force-n', '300,300']) == 0
    capsys.readouterr()
    rows = read_index(out)
    assert len(rows) == 2 and [r.force_n for r in rows] == [300.0, 300.0]
    assert all(r.push.impulse_ns == pytest.approx(30.0) for r in rows)     # 300 N for 0.1 s
    manifest = json.loads((out / 'dataset.json').read_text())
    assert manifest['push_distribution']['force_n'] == [300.0, 300.0]
    # A resume must draw as the dataset did: another range, or the profile's, is refused.
    for other in (['--push-force-n', '250,300'], []):
        assert main(argv + other) == 2
        err = capsys.readouterr().err
        assert 'different generation settings' in err and "push_distribution: {" in err
        assert "'force_n': [300.0, 300.0]" in err
    assert main(argv + ['--push-force-n', '300,300']) == 0        # the same range: finished already
    assert read_index(out) == rows


@pytest.mark.parametrize('value, says', [
    ('5,3', 'the low end must not exceed the high one'),
    ('-1,5', 'the low end must be >= 0'),
    ('nan,300', 'both ends must be finite numbers'),
    ('0,inf', 'both ends must be finite numbers'),
    ('300', 'expected LOW,HIGH'),
    ('100,200,300', 'expected LOW,HIGH'),
    ('low,high', 'expected LOW,HIGH'),
])
def test_a_range_that_is_not_one_is_refused_with_why(value, says, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(['generate', '--trajectories', '1', '--out', str(tmp_path / 'd'), f'--push-force-n={value}'])
    assert exc.value.code == 2
    assert says in capsys.readouterr().err
    assert not (tmp_path / 'd').exists()


def test_a_config_checks_its_range_too():
    from fall_predictor.data.generation import GenerationConfig
    with pytest.raises(ValueError, match='must not exceed'):
        GenerationConfig(seed=0, push_force_n=(300.0, 200.0))
    assert GenerationConfig(seed=0, push_force_n=[300, 300]).push_force_n == (300.0, 300.0)


def test_other_causes_keep_their_runs(tmp_path, capsys):
    """A trip is not a push: its run (and its ranges in the manifest) do not depend on the range."""
    argv = ['generate', '--robot', 'g1_12dof', '--trajectories', '1', '--seed', '0', '--causes', 'trip'] + SHORT
    assert main(argv + ['--out', str(tmp_path / 'a'), '--push-force-n', '300,300']) == 0
    assert main(argv + ['--out', str(tmp_path / 'b')]) == 0
    capsys.readouterr()
    a, b = read_index(tmp_path / 'a'), read_index(tmp_path / 'b')
    assert [r.cause for r in a] == ['trip'] and a == b
    manifests = [json.loads((tmp_path / d / 'dataset.json').read_text()) for d in 'ab']
    assert manifests[0]['cause_ranges'] == manifests[1]['cause_ranges']
