"""The TorchScript reader: module trees, tensors as torch reads them, and explicit refusals.

The fixtures were written by torch (``test/fixtures/policies/make_references.py``); the tensors'
expected values are torch's own reading of the same archive, saved beside it."""
from __future__ import annotations

import os
import pickle
import zipfile
from pathlib import Path

import numpy as np
import pytest

from fall_predictor.robot.torchscript import ScriptModule, TorchScriptError, read_torchscript

FIXTURES = Path(__file__).resolve().parent / 'fixtures' / 'policies'
G1_POLICY = (Path(__file__).resolve().parents[1] / 'fall_predictor' / 'profiles' / 'g1_12dof'
             / 'controllers' / 'unitree_rl_gym' / 'motion.pt')
REFS = np.load(FIXTURES / 'references.npz')


def test_unitree_g1_policy_tree():
    """Unitree's exported LSTM policy: class names, attribute order, tensor shapes, and the LSTM's
    hyper-parameters from the compiled code's constants."""
    archive = read_torchscript(G1_POLICY)
    root = archive.module
    assert archive.root == 'policy_lstm_1' and archive.version == 3
    assert root.qualified_name == '__torch__.legged_gym.utils.helpers.PolicyExporterLSTM'
    assert list(root.attributes) == ['hidden_state', 'cell_state', 'training', '_is_full_backward_hook',
                                     'is_recurrent', 'actor', 'memory']
    assert root.attributes['hidden_state'].shape == (1, 1, 64)
    assert not root.attributes['cell_state'].any()
    memory = root.attributes['memory']
    assert memory.qualified_name == '__torch__.torch.nn.modules.rnn.LSTM'
    assert memory.type_name == 'LSTM' and memory.python_module == 'torch.nn.modules.rnn'
    assert {k: memory.constants[k] for k in ('input_size', 'hidden_size', 'num_layers', 'bidirectional',
                                             'proj_size', 'batch_first')} == {
        'input_size': 47, 'hidden_size': 64, 'num_layers': 1, 'bidirectional': False, 'proj_size': 0,
        'batch_first': False}
    shapes = {k: v.shape for k, v in memory.tensors()}
    assert shapes == {'weight_ih_l0': (256, 47), 'weight_hh_l0': (256, 64), 'bias_ih_l0': (256,),
                      'bias_hh_l0': (256,)}
    assert all(v.dtype == np.float32 for _, v in memory.tensors())
    actor = root.attributes['actor']
    assert [(k, m.type_name) for k, m in actor.modules()] == [('0', 'Linear'), ('1', 'ELU'), ('2', 'Linear')]
    assert actor.attributes['2'].qualified_name == '__torch__.torch.nn.modules.linear.___torch_mangle_0.Linear'
    assert actor.attributes['2'].python_module == 'torch.nn.modules.linear'
    assert actor.attributes['1'].constants['alpha'] == 1.0
    assert 'memory: LSTM (weight_ih_l0[256, 47]' in root.describe_tree()


def test_tensors_are_read_as_torch_reads_them():
    """Strided views of one shared storage (a transpose, a slice at an offset), float64, int64,
    bfloat16 (as float32, exactly), bool, and plain attributes."""
    module = read_torchscript(FIXTURES / 'tensors.pt').module
    for name in ('transposed', 'sliced', 'doubles', 'longs', 'bf16', 'flags'):
        got, want = module.attributes[name], REFS[f'tensors_{name}']
        assert got.dtype == want.dtype and got.shape == want.shape, name
        np.testing.assert_array_equal(got, want, err_msg=name)
    assert module.attributes['transposed'].shape == (6, 4)
    assert module.attributes['transposed'][0, 1] == 0.5 * 6 - 3.0        # base[1, 0]
    assert module.attributes['sliced'][0, 0] == 0.5 * 8 - 3.0            # base[1, 2]: offset 8
    assert module.attributes['doubles'][1, 1] == 1e-300
    assert module.attributes['longs'][2] == 2 ** 40
    assert module.attributes['bf16'].tolist() == [0.5, -1.0, 3.140625]
    assert (module.attributes['gain'], module.attributes['label'], module.attributes['sizes']) == (
        2.5, 'probe', [3, 4])
    lin = module.attributes['lin']
    assert isinstance(lin, ScriptModule) and lin.attributes['bias'] is None
    assert lin.attributes['weight'].shape == (2, 3)


def test_a_traced_module_keeps_its_hyper_parameters_in_its_code():
    """torch.jit.trace declares no constants: the ELU's alpha is a literal in its forward."""
    module = read_torchscript(FIXTURES / 'tiny_mlp_traced.pt').module
    elu = module.attributes['1']
    assert elu.type_name == 'ELU' and elu.constants == {}
    assert 'torch.elu(argument_1, 0.69999999999999996)' in elu.code


def _zip(path: Path, files: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, 'w') as archive:
        for name, data in files.items():
            archive.writestr(name, data)
    return path


def test_not_a_torchscript_file_is_refused_in_words(tmp_path):
    with pytest.raises(TorchScriptError, match='no such file'):
        read_torchscript(tmp_path / 'missing.pt')
    text = tmp_path / 'policy.pt'
    text.write_text('not an archive')
    with pytest.raises(TorchScriptError, match=r'policy\.pt: not a TorchScript archive \(not a zip'):
        read_torchscript(text)
    empty = _zip(tmp_path / 'other.pt', {'folder/readme.txt': b'hello'})
    with pytest.raises(TorchScriptError, match=r'other\.pt: a zip file, but not a TorchScript archive'):
        read_torchscript(empty)
    with pytest.raises(TorchScriptError, match=r'state_dict\.pt: a torch\.save\(\) file.*torch\.jit\.script'):
        read_torchscript(FIXTURES / 'state_dict.pt')


def test_unsupported_globals_are_refused_and_never_run(tmp_path):
    """A pickle naming any other global (here os.system) is refused by name, not called."""
    data = pickle.dumps(os.system, protocol=2)
    bad = _zip(tmp_path / 'bad.pt', {'bad/data.pkl': data, 'bad/code/__torch__.py': b'', 'bad/version': b'3'})
    with pytest.raises(TorchScriptError, match=r'bad\.pt: holds the global (os|posix)\.system'):
        read_torchscript(bad)


def _copy_with(source: Path, target: Path, replace: dict[str, bytes], drop: tuple[str, ...] = ()) -> Path:
    with zipfile.ZipFile(source) as archive:
        files = {n: archive.read(n) for n in archive.namelist() if n not in drop}
    files.update(replace)
    return _zip(target, files)


def test_damaged_storages_are_refused_in_words(tmp_path):
    short = _copy_with(FIXTURES / 'tensors.pt', tmp_path / 'short.pt', {'tensors/data/1': b'\0' * 8})
    with pytest.raises(TorchScriptError, match=r"short\.pt: storage file 'tensors/data/1' has 8 bytes.*"
                                               r"4 float64 elements need 32"):
        read_torchscript(short)
    missing = _copy_with(FIXTURES / 'tensors.pt', tmp_path / 'missing.pt', {}, drop=('tensors/data/2',))
    with pytest.raises(TorchScriptError, match=r"missing\.pt: storage file 'tensors/data/2' is missing"):
        read_torchscript(missing)
