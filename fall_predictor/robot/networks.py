"""Learned policy networks run without torch: in numpy from a TorchScript file, or in onnxruntime.

:func:`load_network` gives an object with ``reset()``, ``__call__(obs) -> action`` (both 1-D),
``input_size``, ``output_size``, ``recurrent`` and a one-line ``describe()``:

* ``.pt`` (TorchScript, :mod:`~fall_predictor.robot.torchscript`), recognised and run in numpy:

  - a plain ``torch.nn.Sequential`` of ``Linear`` layers and activations (ELU, ReLU, Tanh,
    LeakyReLU, Sigmoid, SELU, Identity, Dropout as in eval mode): :class:`MLP`. humanoid-gym's
    exported actor is one;
  - rsl_rl's recurrent exporter (legged_gym's ``PolicyExporterLSTM``, Isaac Lab's): an ``actor``
    Sequential, a ``memory`` (or ``rnn``) LSTM or GRU with ``hidden_state`` (and ``cell_state``)
    buffers, optionally a ``normalizer`` (Identity, or ``(x - _mean) / (_std + eps)``):
    :class:`RecurrentPolicy`, its state carried between calls and zeroed by ``reset()``;
  - rsl_rl's exporter of a non-recurrent policy (``actor``, ``normalizer``): an :class:`MLP`.
  Anything else is refused with the module tree in the message.
* ``.onnx``: an onnxruntime session on the CPU provider with one thread (:class:`OnnxNetwork`);
  each output whose name ends in ``_out`` is fed back at the next call to the input of the same
  stem ending in ``_in`` (``h_out`` -> ``h_in``, ``c_out`` -> ``c_in``), zeroed by ``reset()``.

Why numpy runs a ``.pt``: onnxruntime cannot read TorchScript (converting needs torch), and numpy
costs no more. Median call, one session (the G1 today: docs/monitor/model_cost.json): Unitree's G1
LSTM policy (47 -> LSTM 64 -> 32 -> 12) 18 us in numpy, 21 us in onnxruntime; humanoid-gym's
XBot-L MLP (705 -> 512 -> 256 -> 128 -> 12) 80 us and 79 us (torch, one thread: 99 and 83 us),
the time to read its 2 MB of weights.

Precision: float32, the weights' dtype and torch's. Against torch's outputs float32 numpy differs
by at most 5e-6 over a 60-step G1 sequence (actions up to 9) and 1e-6 on XBot; float64 by about as
much (3e-6, 8e-7: torch's own rounding) at 2.5 times the cost on XBot (225 us: memory bound).

Every buffer is allocated once; a call copies the observation in, runs matrix-vector products and
in-place ufuncs, and returns a copy of the output (a caller keeping it must not see it change).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Optional, Protocol, Union

import numpy as np

from fall_predictor.robot.torchscript import ScriptModule, TorchScriptError, read_torchscript

DTYPE = np.float32  #: the dtype every numpy network computes in (see the module docstring)
#: PyTorch's SELU constants.
SELU_ALPHA = 1.6732632423543772848170429916717
SELU_SCALE = 1.0507009873554804934193349852946
#: An activation applied in place to x, with a scratch buffer t of the same size.
Activation = Callable[[np.ndarray, np.ndarray], None]


class PolicyNetwork(Protocol):
    """What :func:`load_network` returns."""

    input_size: int
    output_size: int
    recurrent: bool

    def reset(self) -> None: ...

    def __call__(self, obs: np.ndarray) -> np.ndarray: ...

    def describe(self) -> str: ...


# -- activations ---------------------------------------------------------------------------------

def _elu(alpha: float) -> Activation:
    def apply(x: np.ndarray, t: np.ndarray) -> None:
        np.minimum(x, 0.0, out=t)
        np.expm1(t, out=t)
        if alpha != 1.0:
            t *= alpha
        np.maximum(x, 0.0, out=x)
        x += t
    return apply


def _leaky_relu(slope: float) -> Activation:
    def apply(x: np.ndarray, t: np.ndarray) -> None:     # x + (slope - 1) min(x, 0)
        np.minimum(x, 0.0, out=t)
        t *= slope - 1.0
        x += t
    return apply


def _sigmoid(x: np.ndarray, t: Optional[np.ndarray] = None) -> None:
    """1 / (1 + exp(-x)) as 0.5 tanh(x / 2) + 0.5: the same function, no overflow for x << 0."""
    x *= 0.5
    np.tanh(x, out=x)
    x *= 0.5
    x += 0.5


def _selu(x: np.ndarray, t: np.ndarray) -> None:
    _elu(SELU_ALPHA)(x, t)
    x *= SELU_SCALE


#: The activations without hyper-parameters (Dropout: as in eval mode).
SIMPLE_ACTIVATIONS: dict[str, Activation] = {
    'ReLU': lambda x, t: np.maximum(x, 0.0, out=x), 'Tanh': lambda x, t: np.tanh(x, out=x),
    'Sigmoid': _sigmoid, 'SELU': _selu, 'Identity': lambda x, t: None, 'Dropout': lambda x, t: None}


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


# -- numpy networks ------------------------------------------------------------------------------

@dataclass(frozen=True)
class Dense:
    """One Linear layer (``weight`` out x in, ``bias`` or None) and the activations after it."""

    weight: np.ndarray
    bias: Optional[np.ndarray]
    activations: tuple[tuple[str, Activation], ...] = ()


class MLP:
    """A multilayer perceptron (after an optional input normalizer) in preallocated buffers."""

    recurrent = False

    def __init__(self, layers: list[Dense], normalizer: Optional['Normalizer'] = None,
                 source: str = '') -> None:
        if not layers:
            raise ValueError(f'{source}: an MLP needs at least one Linear layer')
        for k, (a, b) in enumerate(zip(layers, layers[1:])):
            if b.weight.shape[1] != a.weight.shape[0]:
                raise ValueError(f'{source}: Linear layer {k + 1} takes {b.weight.shape[1]} inputs '
                                 f'but layer {k} gives {a.weight.shape[0]}')
        self.layers = [Dense(np.ascontiguousarray(d.weight, DTYPE),
                             None if d.bias is None else np.ascontiguousarray(d.bias, DTYPE),
                             d.activations) for d in layers]
        self.normalizer, self.source = normalizer, source
        self.input_size = int(self.layers[0].weight.shape[1])
        self.output_size = int(self.layers[-1].weight.shape[0])
        if normalizer is not None and normalizer.size != self.input_size:
            raise ValueError(f'{source}: the normalizer has {normalizer.size} entries for '
                             f'{self.input_size} inputs')
        self._input = np.zeros(self.input_size, DTYPE)
        self._outputs = [np.zeros(d.weight.shape[0], DTYPE) for d in self.layers]
        self._scratch = [np.zeros(d.weight.shape[0], DTYPE) for d in self.layers]

    def reset(self) -> None:  # an MLP has no state
        pass

    def run(self, x: np.ndarray) -> np.ndarray:
        """The output buffer for the input ``x`` (the right dtype and size; not copied)."""
        for layer, y, t in zip(self.layers, self._outputs, self._scratch):
            np.matmul(layer.weight, x, out=y)
            if layer.bias is not None:
                y += layer.bias
            for _, apply in layer.activations:
                apply(y, t)
            x = y
        return x

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        _copy_in(self._input, obs, self.source)
        if self.normalizer is not None:
            self.normalizer.apply(self._input)
        return self.run(self._input).copy()

    def shape_text(self) -> str:
        sizes = [self.input_size] + [d.weight.shape[0] for d in self.layers]
        acts = sorted({label for d in self.layers for label, _ in d.activations})
        return '-'.join(map(str, sizes)) + (f' ({", ".join(acts)})' if acts else '')

    def describe(self) -> str:
        norm = ', normalized input' if self.normalizer is not None else ''
        return f'MLP {self.shape_text()}{norm}, numpy float32, from {self.source}'


@dataclass(frozen=True)
class Normalizer:
    """rsl_rl's empirical observation normalization: ``(x - mean) / (std + eps)``."""

    mean: np.ndarray
    denominator: np.ndarray

    @property
    def size(self) -> int:
        return int(self.mean.size)

    def apply(self, x: np.ndarray) -> None:
        x -= self.mean
        x /= self.denominator


class _LSTMLayer:
    """One LSTM layer in PyTorch's convention: gates i, f, g, o from ``W_ih x + b_ih + W_hh h +
    b_hh``; ``c = f c + i g``, ``h = o tanh(c)``. [x; h] is one buffer, so each step is one
    matrix-vector product with [W_ih | W_hh]."""

    def __init__(self, w_ih: np.ndarray, w_hh: np.ndarray, b_ih: np.ndarray, b_hh: np.ndarray) -> None:
        n = self.hidden = w_hh.shape[1]
        self.inputs = w_ih.shape[1]
        self.weight = np.ascontiguousarray(np.hstack([w_ih, w_hh]), DTYPE)
        self.bias = (b_ih + b_hh).astype(DTYPE)
        self.xh = np.zeros(self.inputs + n, DTYPE)
        self.x, self.h = self.xh[:self.inputs], self.xh[self.inputs:]
        self.c, self.g, self.gates = np.zeros(n, DTYPE), np.zeros(n, DTYPE), np.zeros(4 * n, DTYPE)

    def reset(self) -> None:
        self.h[:], self.c[:] = 0.0, 0.0

    def step(self) -> np.ndarray:
        """Advance from ``self.x`` (filled by the caller); returns ``self.h``."""
        n, gates, g = self.hidden, self.gates, self.g
        np.matmul(self.weight, self.xh, out=gates)
        gates += self.bias
        np.tanh(gates[2 * n:3 * n], out=g)
        _sigmoid(gates)                              # i, f, o (the g part is not used)
        self.c *= gates[n:2 * n]
        g *= gates[:n]
        self.c += g
        np.tanh(self.c, out=self.h)
        self.h *= gates[3 * n:]
        return self.h


class _GRULayer:
    """One GRU layer in PyTorch's convention: gates r, z, n; ``n = tanh(W_in x + b_in + r (W_hn h
    + b_hn))``, ``h = n + z (h - n)``."""

    def __init__(self, w_ih: np.ndarray, w_hh: np.ndarray, b_ih: np.ndarray, b_hh: np.ndarray) -> None:
        n = self.hidden = w_hh.shape[1]
        self.inputs = w_ih.shape[1]
        self.w_ih, self.w_hh = (np.ascontiguousarray(w, DTYPE) for w in (w_ih, w_hh))
        self.b_ih, self.b_hh = b_ih.astype(DTYPE), b_hh.astype(DTYPE)
        self.x, self.h = np.zeros(self.inputs, DTYPE), np.zeros(n, DTYPE)
        self.gi, self.gh = np.zeros(3 * n, DTYPE), np.zeros(3 * n, DTYPE)

    def reset(self) -> None:
        self.h[:] = 0.0

    def step(self) -> np.ndarray:
        n, gi, gh = self.hidden, self.gi, self.gh
        np.matmul(self.w_ih, self.x, out=gi)
        gi += self.b_ih
        np.matmul(self.w_hh, self.h, out=gh)
        gh += self.b_hh
        gi[:2 * n] += gh[:2 * n]
        _sigmoid(gi[:2 * n])                         # r, z
        gh[2 * n:] *= gi[:n]
        gi[2 * n:] += gh[2 * n:]
        np.tanh(gi[2 * n:], out=gi[2 * n:])          # n
        np.subtract(self.h, gi[2 * n:], out=self.h)
        self.h *= gi[n:2 * n]
        self.h += gi[2 * n:]
        return self.h


class RecurrentPolicy:
    """rsl_rl's recurrent policy: [normalizer,] LSTM or GRU layers, then the actor MLP; the
    recurrent state is kept between calls and zeroed by :meth:`reset`."""

    recurrent = True

    def __init__(self, kind: str, layers: list[Any], actor: MLP,
                 normalizer: Optional[Normalizer] = None, source: str = '') -> None:
        if actor.input_size != layers[-1].hidden:
            raise ValueError(f'{source}: the actor takes {actor.input_size} inputs but the '
                             f'{kind} gives {layers[-1].hidden}')
        self.kind, self.layers, self.actor = kind, layers, actor
        self.normalizer, self.source = normalizer, source
        self.input_size, self.output_size = layers[0].inputs, actor.output_size
        self.reset()

    def reset(self) -> None:
        for layer in self.layers:
            layer.reset()

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        first = self.layers[0]
        _copy_in(first.x, obs, self.source)
        if self.normalizer is not None:
            self.normalizer.apply(first.x)
        h = first.step()
        for layer in self.layers[1:]:
            layer.x[:] = h
            h = layer.step()
        return self.actor.run(h).copy()

    def describe(self) -> str:
        norm = 'normalized input, ' if self.normalizer is not None else ''
        return (f'rsl_rl recurrent policy: {norm}{self.kind} {self.input_size}->'
                f'{self.layers[0].hidden} x{len(self.layers)} layer(s), then MLP '
                f'{self.actor.shape_text()}; numpy float32, from {self.source}')


def _copy_in(buffer: np.ndarray, obs: np.ndarray, source: str) -> None:
    if getattr(obs, 'shape', None) != buffer.shape:
        raise ValueError(f'{source}: the observation must be a 1-D array of {buffer.size} values, '
                         f'got shape {getattr(obs, "shape", type(obs).__name__)}')
    np.copyto(buffer, obs, casting='same_kind')


# -- recognising a TorchScript module tree -------------------------------------------------------

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


# -- onnxruntime ---------------------------------------------------------------------------------

class OnnxNetwork:
    """An ONNX policy in onnxruntime (CPU, one thread, float32), recurrent state carried from
    each ``<stem>_out`` output to the ``<stem>_in`` input."""

    def __init__(self, path: Path) -> None:
        import onnxruntime as ort     # only here: the numpy networks do not need it

        options = ort.SessionOptions()
        options.intra_op_num_threads = options.inter_op_num_threads = 1
        options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        options.log_severity_level = 3
        try:
            self.session = ort.InferenceSession(str(path), options, providers=['CPUExecutionProvider'])
        except Exception as exc:  # onnxruntime raises its own exception types
            raise ValueError(f'{path}: onnxruntime cannot load it: {exc}') from exc
        self.source = path.name
        inputs = {i.name: i for i in self.session.get_inputs()}
        outputs = [o.name for o in self.session.get_outputs()]
        self.pairs = [(o, o[:-4] + '_in') for o in outputs
                      if o.endswith('_out') and o[:-4] + '_in' in inputs]
        state_inputs = {i for _, i in self.pairs}
        obs = [n for n in inputs if n not in state_inputs]
        actions = [o for o in outputs if o not in {p for p, _ in self.pairs}]
        if len(obs) != 1 or len(actions) != 1:
            raise ValueError(f'{path}: expected one observation input and one action output besides '
                             f'the <name>_in/<name>_out state pairs; inputs {list(inputs)}, outputs {outputs}')
        for info in inputs.values():
            if info.type != 'tensor(float)':
                raise ValueError(f'{path}: input {info.name!r} is {info.type}, expected tensor(float)')
        self.obs_name, self.action_name = obs[0], actions[0]
        self._feed: dict[str, np.ndarray] = {n: np.zeros(_shape(inputs[n].shape), np.float32)
                                             for n in inputs}
        self._obs = self._feed[self.obs_name].reshape(-1)
        self.input_size = int(self._obs.size)
        self._names = [self.action_name] + [o for o, _ in self.pairs]
        out_shape = [o.shape for o in self.session.get_outputs() if o.name == self.action_name][0]
        self.output_size = int(np.prod(_shape(out_shape)))
        self.recurrent = bool(self.pairs)

    def reset(self) -> None:
        for _, name in self.pairs:
            self._feed[name] = np.zeros_like(self._feed[name])

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        _copy_in(self._obs, obs, self.source)
        results = self.session.run(self._names, self._feed)
        for (_, name), value in zip(self.pairs, results[1:]):
            self._feed[name] = value
        return results[0].reshape(-1)

    def describe(self) -> str:
        state = f', state {", ".join(f"{o}->{i}" for o, i in self.pairs)}' if self.pairs else ''
        return (f'ONNX {self.obs_name}[{self.input_size}] -> {self.action_name}[{self.output_size}]'
                f'{state}; onnxruntime CPU, 1 thread, from {self.source}')


def _shape(dims: list) -> tuple[int, ...]:
    """An ONNX input shape with its symbolic (batch) dimensions set to 1."""
    return tuple(d if isinstance(d, int) and d > 0 else 1 for d in dims)


def load_network(path: Union[str, Path]) -> Union[MLP, RecurrentPolicy, OnnxNetwork]:
    """The policy network of a ``.pt`` (TorchScript, run in numpy) or ``.onnx`` file."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f'{path}: no such policy file')
    if path.suffix == '.onnx':
        return OnnxNetwork(path)
    if path.suffix in ('.pt', '.pth', '.jit', '.zip'):
        return network_from_module(read_torchscript(path).module, path.name)
    raise ValueError(f'{path}: unknown policy file type {path.suffix!r} (expected .pt (TorchScript) '
                     f'or .onnx)')
