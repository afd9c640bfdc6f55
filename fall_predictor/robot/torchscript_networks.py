"""Policy networks recognised in a TorchScript archive (:mod:`fall_predictor.robot.torchscript`)
and built in numpy (:mod:`fall_predictor.robot.numpy_networks`): a ``torch.nn.Sequential`` MLP,
rsl_rl's exported recurrent policy (LSTM or GRU memory, optional normalizer) or its exported
non-recurrent one; anything else refused with the module tree in the message."""
from __future__ import annotations

import re
from typing import Any, Optional, Union

import numpy as np

from fall_predictor.robot.numpy_networks import (DTYPE, MLP, SIMPLE_ACTIVATIONS, Activation, Dense,
                                                 Normalizer, RecurrentPolicy, _elu, _leaky_relu,
                                                 _GRULayer, _LSTMLayer)
from fall_predictor.robot.torchscript import ScriptModule, TorchScriptError

def _hyper(module: ScriptModule, constant: str, function: str, where: str) -> float:
    """A layer's hyper-parameter: its ``Final`` constant (scripted), else the literal its
    ``forward`` passes to ``torch.<function>`` (traced, and scripted code that inlines it)."""
    if constant in module.constants:
        return float(module.constants[constant])
    match = re.search(rf'\b{function}_?\(\s*\w+\s*,\s*([-+0-9.eE]+)', module.code)
    if match is None:
        raise TorchScriptError(f'{where}: the archive does not say the {module.type_name}\'s '
                               f'{constant} (neither a constant nor a literal in its forward)')
    return float(match.group(1))


def _activation(module: ScriptModule, where: str) -> tuple[str, Activation]:
    """(label, in-place function) of a torch.nn activation module; TorchScriptError otherwise."""
    name = module.type_name
    if not module.python_module.startswith('torch.nn.modules'):
        raise TorchScriptError(f'{where}: {module.qualified_name} is not a torch.nn layer')
    if name == 'ELU':
        alpha = _hyper(module, 'alpha', 'elu', where)
        return (f'ELU({alpha:g})' if alpha != 1.0 else 'ELU'), _elu(alpha)
    if name == 'LeakyReLU':
        slope = _hyper(module, 'negative_slope', 'leaky_relu', where)
        return f'LeakyReLU({slope:g})', _leaky_relu(slope)
    if name in SIMPLE_ACTIVATIONS:
        return name, SIMPLE_ACTIVATIONS[name]
    raise TorchScriptError(f'{where}: layer {name} ({module.qualified_name}) is not supported '
                           f'(supported: Linear, ELU, ReLU, Tanh, LeakyReLU, Sigmoid, SELU, '
                           f'Identity, Dropout)')


def _is_torch_nn(module: Any, name: str) -> bool:
    return (isinstance(module, ScriptModule) and module.type_name == name
            and module.python_module.startswith('torch.nn.modules'))


def _tensor(module: ScriptModule, name: str, where: str, ndim: int) -> np.ndarray:
    value = module.attributes.get(name)
    if not isinstance(value, np.ndarray) or value.ndim != ndim or value.dtype.kind != 'f':
        raise TorchScriptError(f'{where}: expected a {ndim}-D float tensor {name!r}, got '
                               f'{getattr(value, "shape", value)!r}')
    return value


def _mlp_layers(seq: ScriptModule, where: str) -> list[Dense]:
    children = sorted(seq.modules(), key=lambda kv: int(kv[0]) if kv[0].isdigit() else -1)
    layers: list[Dense] = []
    for name, child in children:
        at = f'{where}.{name}'
        if _is_torch_nn(child, 'Linear'):
            bias = child.attributes.get('bias')
            layers.append(Dense(_tensor(child, 'weight', at, 2),
                                None if bias is None else _tensor(child, 'bias', at, 1)))
        elif not layers:
            raise TorchScriptError(f'{at}: the Sequential must start with a Linear layer, '
                                   f'found {child.type_name}')
        else:
            last = layers[-1]
            layers[-1] = Dense(last.weight, last.bias, last.activations + (_activation(child, at),))
    return layers


def _normalizer(module: Optional[ScriptModule], where: str) -> Optional[Normalizer]:
    if module is None or _is_torch_nn(module, 'Identity'):
        return None
    if '_mean' in module.attributes and '_std' in module.attributes:
        eps = float(module.constants.get('eps', module.attributes.get('eps', 1e-2)))
        mean = _tensor(module, '_mean', where, module.attributes['_mean'].ndim).reshape(-1)
        std = _tensor(module, '_std', where, module.attributes['_std'].ndim).reshape(-1)
        return Normalizer(mean.astype(DTYPE), (std + eps).astype(DTYPE))
    raise TorchScriptError(f'{where}: normalizer {module.qualified_name} not recognised '
                           f'(expected Identity or one with _mean and _std buffers)')


def _recurrent_layers(rnn: ScriptModule, where: str) -> list[Any]:
    kind = rnn.type_name
    names = [n for n, _ in rnn.tensors()]
    if any(n.endswith('_reverse') for n in names) or rnn.constants.get('bidirectional'):
        raise TorchScriptError(f'{where}: a bidirectional {kind} cannot run one step at a time')
    if any(n.startswith('weight_hr') for n in names) or rnn.constants.get('proj_size', 0):
        raise TorchScriptError(f'{where}: an LSTM with projections (proj_size > 0) is not supported')
    count = int(rnn.constants.get('num_layers', sum(n.startswith('weight_ih_l') for n in names)))
    layers = []
    for k in range(count):
        at = f'{where} layer {k}'
        w_ih, w_hh = _tensor(rnn, f'weight_ih_l{k}', at, 2), _tensor(rnn, f'weight_hh_l{k}', at, 2)
        hidden, gates = w_hh.shape[1], 4 if kind == 'LSTM' else 3
        zero = np.zeros(gates * hidden, w_ih.dtype)
        b_ih = _tensor(rnn, f'bias_ih_l{k}', at, 1) if f'bias_ih_l{k}' in names else zero
        b_hh = _tensor(rnn, f'bias_hh_l{k}', at, 1) if f'bias_hh_l{k}' in names else zero
        if w_hh.shape != (gates * hidden, hidden) or w_ih.shape[0] != gates * hidden \
                or b_ih.shape != zero.shape or b_hh.shape != zero.shape:
            raise TorchScriptError(f'{at}: weights of shapes {w_ih.shape}, {w_hh.shape} are not '
                                   f'those of a {kind}')
        if layers and w_ih.shape[1] != layers[-1].hidden:
            raise TorchScriptError(f'{at}: takes {w_ih.shape[1]} inputs, layer {k - 1} gives '
                                   f'{layers[-1].hidden}')
        layers.append((_LSTMLayer if kind == 'LSTM' else _GRULayer)(w_ih, w_hh, b_ih, b_hh))
    if not layers:
        raise TorchScriptError(f'{where}: the {kind} has no layers')
    return layers


def network_from_module(module: ScriptModule, source: str) -> Union[MLP, RecurrentPolicy]:
    """The numpy network of a TorchScript module tree (see the module docstring)."""
    if _is_torch_nn(module, 'Sequential'):
        return MLP(_mlp_layers(module, source), source=source)
    attrs = module.attributes
    actor = attrs.get('actor')
    rnn = attrs.get('memory', attrs.get('rnn'))
    if _is_torch_nn(actor, 'Sequential'):
        normalizer = _normalizer(attrs.get('normalizer'), f'{source}: normalizer')
        mlp = MLP(_mlp_layers(actor, f'{source}: actor'), source=source)
        if rnn is None and not attrs.get('is_recurrent', False):
            return MLP(mlp.layers, normalizer, source)
        if _is_torch_nn(rnn, 'LSTM') and isinstance(attrs.get('cell_state'), np.ndarray) \
                or _is_torch_nn(rnn, 'GRU') and isinstance(attrs.get('hidden_state'), np.ndarray):
            layers = _recurrent_layers(rnn, f'{source}: {rnn.type_name}')
            return RecurrentPolicy(rnn.type_name, layers, mlp, normalizer, source)
    raise TorchScriptError(
        f'{source}: network not recognised: expected a torch.nn.Sequential MLP, or rsl_rl\'s '
        f'exported policy (an actor Sequential with a memory/rnn LSTM and hidden_state and '
        f'cell_state buffers, or a GRU and hidden_state); the archive holds:\n{module.describe_tree()}')
