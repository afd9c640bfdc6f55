"""Bring-up under a learned policy: Unitree's G1 (``g1_12dof``) walked by Unitree's policy in MuJoCo,
the monitor on its sensor topics, pushed as dataset trajectories 0 and 1 of seed 2 are; the fall is
predicted before it happens and C_fall takes over, the survived push raises no alarm. What cannot
run so is refused in words."""
from __future__ import annotations

import io
import json
import re
from pathlib import Path

import pytest
from test_bringup import _node_processes_on
from test_nodes_support import test_domain_id, write_momentum_model

from fall_predictor.profiles.profile import load_profile
from fall_predictor.ros.bringup import node_overrides, run_bringup
from fall_predictor.ros.errors import BringupError
from fall_predictor.sim.policy_runs import commanded_pushes
from fall_predictor.sim.pushes import trajectory_seed

ROBOT = 'g1_12dof'
POLICY = load_profile(ROBOT).controller_profile()
#: Dataset trajectories 0 and 1 of seed 2 (commanded_pushes): offline (``fall-predictor simulate
#: --robot g1_12dof`` with each push, command and onset) the first, 92 N at 36 deg at 2.150 s
#: walking at (0.16, -0.12, 0.31), is survived, its momentum at most 12.3 kg m/s; the second,
#: 966 N at -165 deg at 2.040 s walking at (0.54, 0.21, -0.29), passes the hand-built model's
#: 25 kg m/s at 2.086 s, within the push, and fells the robot at 2.444 s.
SEED = 2
HORIZON_S = 0.5


def test_the_g1_under_its_policy_falls_predicted_and_survives_unalarmed(tmp_path: Path) -> None:
    domain = test_domain_id(186)
    out = io.StringIO()
    results = run_bringup(2, SEED, out, domain_id=domain, robot=ROBOT,
                          model_path=write_momentum_model(tmp_path / 'model.json'),
                          horizon_s=HORIZON_S, log_dir=tmp_path / 'logs')
    assert _node_processes_on(domain) == []
    assert [json.loads(line) for line in out.getvalue().splitlines()] == results
    pushes = []
    for index, result in enumerate(results):
        command, push = commanded_pushes(POLICY).sample(trajectory_seed(SEED, index))
        pushes.append(push)
        assert (result['robot'], result['controller'], result['simulator']) == (
            ROBOT, 'unitree_rl_gym', 'mujoco')
        assert result['command'] == list(command)
        assert result['push']['force_n'] == push.force_n and result['push']['t_push'] == push.t_push
        assert not result['false_alarm_before_push']
    survived, fell = results
    assert survived['outcome'] == 'no_fall' and survived['t_predict'] is None
    assert survived['controller_mode'] == 'balance' and survived['stopped_by'] == 'horizon'
    assert survived['t_end'] >= pushes[0].t_force_end + HORIZON_S - 1e-9
    # Predicted after the push and before the fall, and C_fall took over before the robot was
    # down. How long after the momentum passed the threshold depends on the machine: unpaced, the
    # lock-stepped simulator and policy do not wait for the monitor, whose best-effort inputs
    # (REP 2003) skip to their newest samples when it lags (a loaded run predicted at 2.152 s, an
    # idle one at 2.096 s).
    assert fell['outcome'] == 'fall_predicted' and fell['controller_mode'] == 'fall'
    assert pushes[1].t_push <= fell['t_predict'] < fell['t_fallen'] and fell['stopped_by'] == 'fallen'
    log = (tmp_path / 'logs' / 'controller_node.log').read_text()
    assert 'controller ready: unitree_rl_gym on robot g1_12dof' in log
    switches = re.findall(r'C_fall from t = (\d+\.\d+) s', log)
    assert len(switches) == 1 and fell['t_predict'] <= float(switches[0]) < fell['t_fallen']
    simulator_log = (tmp_path / 'logs' / 'simulator_node.log').read_text()
    assert 'g1_12dof under unitree_rl_gym in mujoco (2 ms steps)' in simulator_log


def test_the_policy_nodes_get_the_controller_and_walk_on_the_sensors() -> None:
    names, overrides = node_overrides(0.0, None, True, True, 'simulator', ROBOT, None,
                                      'unitree_rl_gym', 'mujoco')
    assert 'state_estimator_node' in names
    for node in ('simulator_node', 'controller_node'):
        assert overrides[node]['controller'] == 'unitree_rl_gym'
        assert overrides[node]['simulator'] == 'mujoco'
    assert overrides['simulator_node']['publish_sensors'] == 'true'
    assert 'ground_truth' not in overrides['controller_node']     # a policy reads the sensors
    _, c_bal = node_overrides(0.0, None, True, True, 'simulator', ROBOT, None, 'c_bal')
    assert c_bal['controller_node'] == {'robot': ROBOT, 'controller': 'c_bal', 'ground_truth': 'true'}


def test_a_policy_with_the_true_state_or_without_a_model_is_refused_in_words(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(BringupError, match='learned policy: it walks on the robot\'s sensor topics'):
        run_bringup(1, SEED, robot=ROBOT, sensors=False, log_dir=tmp_path)
    monkeypatch.setattr('fall_predictor.ros.bringup.package_share_dir', lambda: tmp_path)
    from fall_predictor.profiles.profile import load_profile
    missing = tmp_path / 'models' / load_profile(ROBOT).model_for()
    with pytest.raises(BringupError, match=re.escape(f'{missing} does not exist') + '.*pass --model'):
        run_bringup(1, SEED, robot=ROBOT, sensors=True, log_dir=tmp_path)
    with pytest.raises(BringupError, match="robot 'g1_12dof' has no controller 'walker'"):
        run_bringup(1, SEED, robot=ROBOT, sensors=True, controller='walker', log_dir=tmp_path)
