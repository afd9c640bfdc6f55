"""C_bal walks and recovers from moderate pushes; strong pushes fell it; C_fall is one-way."""
import numpy as np
import pytest

from fall_predictor.controllers import BalanceController, ControllerSwitch, GaitConfig
from fall_predictor.records import PushSpec
from fall_predictor.trajectory import run_trajectory


def test_walks_60_s_without_falling_or_reflex():
    result = run_trajectory(None, 60.0)
    assert not result.fallen
    assert result.t_reflex is None
    com = result.com
    assert com[:, 2].min() > 0.55
    assert com[-1, 0] > 5.0 and abs(com[-1, 1]) < 0.3      # it walks forward, straight
    # It really walks: single support alternates between the feet.
    left_only = [len(m.left_contacts) > 0 and len(m.right_contacts) == 0 for m in result.measurements]
    right_only = [len(m.right_contacts) > 0 and len(m.left_contacts) == 0 for m in result.measurements]
    assert sum(left_only) > 20000 and sum(right_only) > 20000


def test_moderate_push_fires_the_reflex_widens_the_stance_and_lowers_the_com():
    push = PushSpec(force_n=120.0, angle_deg=90.0, height_m=0.1, t_push=2.3)
    result = run_trajectory(push, 6.0)
    assert not result.fallen
    assert result.t_reflex is not None and push.t_push <= result.t_reflex < push.t_force_end + 0.3
    last = result.measurements[-1]
    assert abs(last.left_foot[1] - last.right_foot[1]) >= 0.25     # wider than 0.18 walking
    assert last.com[2] < result.measurements[0].com[2] - 0.03
    assert np.abs(last.lin_mom[:2]).max() < 1.0                        # settled


def test_strong_push_ends_fallen():
    result = run_trajectory(PushSpec(force_n=450.0, angle_deg=0.0, height_m=0.2, t_push=2.3), 6.0)
    assert result.fallen
    assert 2.4 < result.t_fallen < 6.0


def test_switch_to_fall_control_is_one_way_and_freezes_the_target():
    t_trigger = 2.5
    result = run_trajectory(PushSpec(300.0, 0.0, 0.1, 2.3), 4.0,
                            fall_trigger=lambda m: m.t >= t_trigger)
    assert result.t_switch == pytest.approx(t_trigger)
    switch = ControllerSwitch(BalanceController(GaitConfig()))
    q0, _ = switch.balance.initial_posture()
    assert switch.trigger_fall(1.0) is True
    assert switch.trigger_fall(2.0) is False
    assert switch.mode == 'fall' and switch.t_switch == 1.0
