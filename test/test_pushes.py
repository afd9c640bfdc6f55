"""The push protocol (fall_predictor.sim.pushes): method §3 ranges, gait variety, determinism."""
import numpy as np
import pytest

from fall_predictor.robot.balance_controller import BalanceController, GaitConfig, ReflexConfig
from fall_predictor.sim.pushes import PushDistribution, trajectory_seed
from fall_predictor.sim.pybullet_world import PybulletWorld


def test_gaits_and_pushes_cover_the_amended_ranges_and_no_more():
    dist = PushDistribution()
    draws = [dist.sample_with_gait(trajectory_seed(3, i)) for i in range(2000)]
    speed = np.array([g.step_length_m / (g.single_support_s + g.double_support_s) for g, _ in draws])
    single = np.array([g.single_support_s for g, _ in draws])
    width = np.array([2 * g.stance_half_width_m for g, _ in draws])
    standing = np.array([g.standing for g, _ in draws])
    assert 0.0 <= speed.min() < 0.01 and 0.24 < speed.max() <= 0.25
    assert 0.45 <= single.min() < 0.46 and 0.69 < single.max() <= 0.7
    assert all(g.double_support_s == 0.2 for g, _ in draws)
    assert 0.16 <= width.min() < 0.161 and 0.219 < width.max() <= 0.22
    # 10 % stand still: 200 expected of 2000, binomial sd ~13.
    assert 160 < standing.sum() < 240
    # The onset is uniform over one cycle of the trajectory's own gait, after the settling time.
    for gait, push in draws:
        cycle = 2 * (gait.single_support_s + gait.double_support_s)
        assert dist.settle_s <= push.t_push <= dist.settle_s + cycle + 1e-3


def test_a_trajectory_draws_the_same_gait_and_push_whatever_else_is_drawn():
    dist = PushDistribution()
    first = dist.sample_with_gait(trajectory_seed(7, 42))
    [dist.sample_with_gait(trajectory_seed(7, i)) for i in range(10)]
    assert dist.sample_with_gait(trajectory_seed(7, 42)) == first
    assert dist.sample_with_gait(trajectory_seed(7, 43)) != first


def test_a_standing_gait_keeps_both_feet_where_they_are():
    with PybulletWorld() as sim:
        controller = BalanceController(GaitConfig(standing=True), ReflexConfig())
        q0, torso0 = controller.initial_posture()
        m = sim.reset(q0, torso0)
        start = (m.left_foot.copy(), m.right_foot.copy())
        while sim.t < 3.0:
            sim.set_joint_targets(controller.update(m))
            m = sim.step()
            if sim.t > 0.2:      # the robot starts just above the ground
                assert len(m.left_contacts) and len(m.right_contacts)
        assert controller.reflex_event is None
        assert m.left_foot[:2] == pytest.approx(start[0][:2], abs=0.005)
        assert m.right_foot[:2] == pytest.approx(start[1][:2], abs=0.005)


def test_a_dataset_draws_each_push_onset_over_one_cycle_of_its_robots_own_gait(monkeypatch):
    """The G1 walks 0.35 s of single support, a 1.1 s cycle; generation drew its onsets over
    the default gait's 1.4 s cycle, so the phases of one step in five were drawn twice."""
    from fall_predictor.data import generation
    from fall_predictor.sim import trajectory
    from fall_predictor.sim.pushes import robot_gait

    class Drawn(Exception):
        pass

    def capture(push, *args, **kwargs):
        raise Drawn(push)

    monkeypatch.setattr(trajectory, 'run_trajectory', capture)
    monkeypatch.setattr(generation, '_walk_prefix', lambda config: None)
    config = generation.GenerationConfig(seed=5, robot='g1', gait_variety=False)
    gait = robot_gait('g1')
    cycle_s = PushDistribution().walk_cycle_s(gait)
    assert (gait.single_support_s, cycle_s) == (0.35, pytest.approx(1.1))
    onsets = []
    for index in range(60):
        with pytest.raises(Drawn) as drawn:
            generation.simulate_one(config, index)
        onsets.append(drawn.value.args[0].t_push - config.push_distribution.settle_s)
    assert 0.0 <= min(onsets) and max(onsets) <= cycle_s
    assert max(onsets) > 0.9 * cycle_s                  # over the whole cycle
    assert robot_gait('asimo_like') == GaitConfig()     # the default robot: as before
