"""The policy networks without torch, each against torch's own outputs (saved by
``test/fixtures/policies/make_references.py``), and numpy against onnxruntime on the same network."""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

from fall_predictor.robot import numpy_networks as networks
from fall_predictor.robot.networks import load_network
from fall_predictor.robot.numpy_networks import MLP, RecurrentPolicy
from fall_predictor.robot.onnx_network import OnnxNetwork
from fall_predictor.robot.torchscript import TorchScriptError

FIXTURES = Path(__file__).resolve().parent / 'fixtures' / 'policies'
G1_POLICY = (Path(__file__).resolve().parents[1] / 'fall_predictor' / 'profiles' / 'g1_12dof'
             / 'controllers' / 'unitree_rl_gym' / 'motion.pt')
REFS = np.load(FIXTURES / 'references.npz')
#: Torch and numpy sum in different orders: float32 results agree to ~1e-6 of their size.
TOLERANCE = 1e-5


def run(network, observations: np.ndarray) -> np.ndarray:
    network.reset()
    return np.stack([network(o) for o in observations])


@pytest.mark.parametrize('name', ['tiny_mlp.pt', 'tiny_mlp_traced.pt'])
def test_mlp_with_every_activation_equals_torch(name):
    network = load_network(FIXTURES / name)
    assert isinstance(network, MLP) and not network.recurrent
    assert (network.input_size, network.output_size) == (10, 4)
    assert 'ELU(0.7)' in network.describe() and 'LeakyReLU(0.2)' in network.describe()
    out = run(network, REFS['tiny_obs'])
    np.testing.assert_allclose(out, REFS['tiny_mlp'], rtol=0, atol=TOLERANCE)
    assert np.ptp(REFS['tiny_mlp']) > 0.5                 # the outputs do vary with the input


def test_lstm_policy_equals_torch_over_a_sequence_and_reset_restarts_it():
    """legged_gym's exporter layout, 2 LSTM layers: the state is carried from call to call."""
    network = load_network(FIXTURES / 'tiny_lstm.pt')
    assert isinstance(network, RecurrentPolicy) and network.recurrent and network.kind == 'LSTM'
    assert len(network.layers) == 2 and (network.input_size, network.output_size) == (10, 4)
    out = run(network, REFS['tiny_obs'])
    np.testing.assert_allclose(out, REFS['tiny_lstm'], rtol=0, atol=TOLERANCE)
    network.reset()
    np.testing.assert_array_equal(network(REFS['tiny_obs'][0]), out[0])


def test_gru_policy_with_a_normalizer_equals_torch():
    """Isaac Lab's exporter layout: ``rnn`` = GRU, an empirical ``normalizer``."""
    network = load_network(FIXTURES / 'tiny_gru.pt')
    assert network.kind == 'GRU' and network.normalizer is not None
    np.testing.assert_allclose(run(network, REFS['tiny_obs']), REFS['tiny_gru'], rtol=0, atol=TOLERANCE)


def test_unitree_g1_policy_equals_torch_over_60_steps():
    """Unitree's G1 policy (LSTM 47->64, MLP 64-32-12) over a 60-step sequence: state carried
    (each step from a zero state gives other actions), reset gives the first output again."""
    network = load_network(G1_POLICY)
    assert (network.input_size, network.output_size, network.recurrent) == (47, 12, True)
    obs, want = REFS['g1_obs'], REFS['g1_actions']
    out = run(network, obs)
    np.testing.assert_allclose(out, want, rtol=0, atol=TOLERANCE)
    stateless = np.stack([run(network, o[None])[0] for o in obs])
    assert np.abs(stateless[1:] - want[1:]).max() > 0.1
    network.reset()
    np.testing.assert_array_equal(network(obs[0]), out[0])
    assert '\n' not in network.describe() and 'LSTM 47->64' in network.describe()


def _xbot_policy(tmp_path: Path) -> Path:
    """humanoid-gym's XBot-L policy (2 MB, not a fixture): ``XBOT_POLICY``, or read from a local
    humanoid-gym git repository (``HUMANOID_GYM_REPO``)."""
    if os.environ.get('XBOT_POLICY'):
        return Path(os.environ['XBOT_POLICY'])
    repo = Path(os.environ.get('HUMANOID_GYM_REPO', ''))       # no default: a clone is the user's
    if not os.environ.get('HUMANOID_GYM_REPO') or not repo.exists():
        pytest.skip('humanoid-gym policy not at hand (set XBOT_POLICY or HUMANOID_GYM_REPO)')
    path = tmp_path / 'policy_example.pt'
    blob = subprocess.run(['git', '-C', str(repo), 'show', 'HEAD:logs/XBot_ppo/exported/policies/policy_example.pt'],
                          capture_output=True, check=True).stdout
    path.write_bytes(blob)
    return path


def test_humanoid_gym_xbot_policy_equals_torch(tmp_path):
    network = load_network(_xbot_policy(tmp_path))
    assert isinstance(network, MLP) and network.shape_text() == '705-512-256-128-12 (ELU)'
    refs = np.load(FIXTURES / 'xbot_reference.npz')
    np.testing.assert_allclose(run(network, refs['obs']), refs['actions'], rtol=0, atol=TOLERANCE)


def test_onnx_networks_equal_torch_and_numpy():
    pytest.importorskip('onnxruntime')
    mlp = load_network(FIXTURES / 'tiny_mlp.onnx')
    assert isinstance(mlp, OnnxNetwork) and not mlp.recurrent
    assert (mlp.input_size, mlp.output_size) == (10, 4)
    np.testing.assert_allclose(run(mlp, REFS['tiny_obs']), REFS['tiny_mlp'], rtol=0, atol=TOLERANCE)
    np.testing.assert_allclose(run(mlp, REFS['tiny_obs']), run(load_network(FIXTURES / 'tiny_mlp.pt'),
                                                               REFS['tiny_obs']), rtol=0, atol=TOLERANCE)
    lstm = load_network(FIXTURES / 'tiny_lstm.onnx')
    assert lstm.recurrent and lstm.pairs == [('h_out', 'h_in'), ('c_out', 'c_in')]
    assert 'h_out->h_in' in lstm.describe()
    out = run(lstm, REFS['tiny_obs'])
    np.testing.assert_allclose(out, REFS['tiny_lstm'], rtol=0, atol=TOLERANCE)
    np.testing.assert_allclose(out, run(load_network(FIXTURES / 'tiny_lstm.pt'), REFS['tiny_obs']),
                               rtol=0, atol=TOLERANCE)
    lstm.reset()
    np.testing.assert_array_equal(lstm(REFS['tiny_obs'][0]), out[0])


def test_the_output_is_the_callers_own_array():
    """A caller keeping the last action must not see it change at the next call."""
    network = load_network(FIXTURES / 'tiny_mlp.pt')
    first = network(REFS['tiny_obs'][0])
    kept = first.copy()
    network(REFS['tiny_obs'][1])
    np.testing.assert_array_equal(first, kept)


def test_activations_against_their_formulas():
    """Each in-place activation against its definition computed in float64."""
    x64 = np.linspace(-120.0, 6.0, 253)
    cases = {
        'elu 0.7': (networks._elu(0.7), np.where(x64 > 0, x64, 0.7 * np.expm1(np.minimum(x64, 0)))),
        'leaky 0.2': (networks._leaky_relu(0.2), np.where(x64 > 0, x64, 0.2 * x64)),
        'leaky 1.5': (networks._leaky_relu(1.5), np.where(x64 > 0, x64, 1.5 * x64)),
        'sigmoid': (networks._sigmoid, 1.0 / (1.0 + np.exp(-x64))),
        'selu': (networks._selu, networks.SELU_SCALE * np.where(
            x64 > 0, x64, networks.SELU_ALPHA * np.expm1(np.minimum(x64, 0)))),
        'tanh': (networks.SIMPLE_ACTIVATIONS['Tanh'], np.tanh(x64)),
        'relu': (networks.SIMPLE_ACTIVATIONS['ReLU'], np.maximum(x64, 0)),
    }
    for name, (apply, want) in cases.items():
        x = x64.astype(np.float32)
        with np.errstate(all='raise'):                    # no overflow for large negative inputs
            apply(x, np.empty_like(x))
        np.testing.assert_allclose(x, want, rtol=1e-6, atol=1e-6, err_msg=name)


def test_what_is_not_recognised_is_said(tmp_path):
    with pytest.raises(TorchScriptError, match=r'(?s)tensors\.pt: network not recognised.*<root>: Tensors'):
        load_network(FIXTURES / 'tensors.pt')
    other = tmp_path / 'policy.h5'
    other.write_bytes(b'x')
    with pytest.raises(ValueError, match=r"unknown policy file type '\.h5'"):
        load_network(other)
    with pytest.raises(ValueError, match='no such policy file'):
        load_network(tmp_path / 'missing.pt')
    network = load_network(FIXTURES / 'tiny_mlp.pt')
    with pytest.raises(ValueError, match=r'1-D array of 10 values, got shape \(1, 10\)'):
        network(np.zeros((1, 10), np.float32))
