"""Mirror augmentation against the reflection y -> -y."""
import numpy as np

from fall_predictor.learning.learners import TreeListLearner
from fall_predictor.learning.mirror import MIRROR_MODES, MIRROR_SIGNS, mirror_trajectory
from fall_predictor.learning.training import fit_strided
from fall_predictor.monitor.contact_modes import ContactMode as M
from fall_predictor.monitor.records import FALLING, BALANCED, FEATURE_NAMES, N_FEATURES
from synthetic_trajectories import FALLING_MODE, LIN_MOM_Y, make_dataset


def test_mode_map_is_the_reflection():
    pairs = {M.L_FRONT_LEFT: M.R_FRONT_RIGHT, M.L_INSIDE: M.R_INSIDE, M.L_BACK: M.R_BACK,
             M.L_LEFT: M.R_RIGHT, M.LR_FRONT: M.LR_FRONT, M.OUTSIDE: M.OUTSIDE}
    for a, b in pairs.items():
        assert MIRROR_MODES[a] == b and MIRROR_MODES[b] == a
    np.testing.assert_array_equal(MIRROR_MODES[MIRROR_MODES], np.arange(16))


def test_feature_signs_follow_polar_and_axial_vectors():
    # r x p with y reflected: polar y flips; axial x and z flip.
    r, p = np.array([0.1, 0.2, 0.6]), np.array([3.0, -2.0, 0.5])
    reflect = np.diag([1.0, -1.0, 1.0])
    L = np.cross(r, p)
    L_mirror = np.cross(reflect @ r, reflect @ p)
    signs = dict(zip(FEATURE_NAMES, MIRROR_SIGNS))
    np.testing.assert_allclose(L_mirror, L * [signs['ang_mom_x'], signs['ang_mom_y'], signs['ang_mom_z']])
    np.testing.assert_allclose(reflect @ r, r * [signs['com_x'], signs['com_y'], signs['com_z']])
    assert MIRROR_SIGNS.shape == (N_FEATURES,)


def test_mirrored_data_teaches_the_mirrored_rule():
    trajectories = make_dataset(4, 4, seed=5)
    mirrored = [mirror_trajectory(t) for t in trajectories]
    assert mirrored[0].trajectory_id.endswith('-mirror')
    np.testing.assert_array_equal(mirror_trajectory(mirrored[0]).X, trajectories[0].X)
    learner = TreeListLearner(max_depth=2)
    lists = fit_strided(mirrored, 0.0, learner, sample_stride=10)
    # The L-LEFT rule "lin_mom_y > ~4.5" becomes the R-RIGHT rule "lin_mom_y < ~-4.5".
    x = np.zeros((2, N_FEATURES))
    x[:, 2] = 0.59
    x[0, LIN_MOM_Y], x[1, LIN_MOM_Y] = -6.5, 6.5
    right = np.full(2, MIRROR_MODES[FALLING_MODE])
    np.testing.assert_array_equal(lists.predict(x, right), [FALLING, BALANCED])
    assert not lists.lists[FALLING_MODE].rules
    # With the augmentation both feet get the rule.
    both = fit_strided(trajectories, 0.0, learner, sample_stride=10, mirror=True)
    np.testing.assert_array_equal(both.predict(x, right), [FALLING, BALANCED])
    x[:, LIN_MOM_Y] *= -1
    np.testing.assert_array_equal(both.predict(x, np.full(2, FALLING_MODE)), [FALLING, BALANCED])


def test_train_mirror_option_gives_lists_that_agree_with_their_mirror_image(tmp_path, capsys):
    """``train --mirror``: a sample and its mirror image get the same prediction (in mirrored
    modes) on nearly every training sample, and the model file says it was mirrored."""
    import json

    from fall_predictor.cli import main
    from fall_predictor.data.dataset import load_features
    from fall_predictor.monitor.model_file import load_model

    out = tmp_path / 'data'
    assert main(['generate', '--trajectories', '3', '--seed', '0', '--out', str(out), '--horizon', '0.8',
                 '--json']) == 0
    plain, mirrored = tmp_path / 'plain.json', tmp_path / 'mirror.json'
    assert main(['train', '--data', str(out), '--state', 'true', '--tau-plus=-0.25', '--out', str(plain)]) == 0
    assert main(['train', '--data', str(out), '--state', 'true', '--tau-plus=-0.25', '--out', str(mirrored),
                 '--mirror', '--json']) == 0
    assert json.loads(capsys.readouterr().out.splitlines()[-1])['mirror'] is True
    lists, metadata = load_model(mirrored)
    assert metadata.mirror and not load_model(plain)[1].mirror
    trajectories = load_features(out, progress=False).trajectories
    X = np.concatenate([t.X for t in trajectories])
    modes = np.concatenate([t.mode for t in trajectories])
    X, modes = X[modes >= 0], modes[modes >= 0]

    def agreement(model_lists):
        """On the samples it calls falling, or calls falling in their mirror image."""
        a = model_lists.predict(X, modes)
        b = model_lists.predict(X * MIRROR_SIGNS, MIRROR_MODES[modes])
        either = (a == FALLING) | (b == FALLING)
        assert either.sum() > 100
        return float(np.mean(a[either] == b[either]))
    assert agreement(lists) >= 0.99
    assert agreement(load_model(plain)[0]) < 0.9       # not symmetric without the option


def test_the_attitude_mirrors_with_roll_and_angular_velocity_x_flipped():
    """Reflecting y: a base rolled to its left (about +x) is rolled to its right in the mirror,
    its pitch unchanged (the fused roll asin(R[2, 1]) flips with R's y row and column)."""
    import dataclasses
    from fall_predictor.learning.mirror import ATTITUDE_MIRROR_SIGNS
    from fall_predictor.monitor.geometry import fused_roll_pitch_of_rotation
    roll, pitch = 0.3, -0.2
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    rotation = (np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
                @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]]))
    reflect = np.diag([1.0, -1.0, 1.0])
    mirrored = fused_roll_pitch_of_rotation(reflect @ rotation @ reflect)
    np.testing.assert_allclose(mirrored, np.array(fused_roll_pitch_of_rotation(rotation))
                               * ATTITUDE_MIRROR_SIGNS[:2])
    np.testing.assert_array_equal(ATTITUDE_MIRROR_SIGNS, [-1.0, 1.0, -1.0, 1.0])
    traj = make_dataset(1, 0, seed=0)[0]
    attitude = np.tile([0.1, 0.2, 0.3, 0.4], (len(traj.t), 1))
    traj = dataclasses.replace(traj, attitude=attitude)
    image = mirror_trajectory(traj)
    np.testing.assert_array_equal(image.attitude, attitude * [-1, 1, -1, 1])
    wide = mirror_trajectory(traj.with_attitude_inputs())
    np.testing.assert_array_equal(wide.X[:, 15:], attitude * [-1, 1, -1, 1])
    np.testing.assert_array_equal(wide.X[:, :15], image.X)
