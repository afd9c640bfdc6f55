"""The policy networks run in numpy (:mod:`fall_predictor.robot.networks` says which files make
them and what they cost): the activations, :class:`Dense` layers, :class:`MLP`,
:class:`Normalizer`, LSTM and GRU layers and :class:`RecurrentPolicy`, in float32.

Every buffer is allocated once; a call copies the observation in, runs matrix-vector products and
in-place ufuncs, and returns a copy of the output (a caller keeping it must not see it change).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Optional

import numpy as np

DTYPE = np.float32  #: the dtype every numpy network computes in (see the module docstring)
#: PyTorch's SELU constants.
SELU_ALPHA = 1.6732632423543772848170429916717
SELU_SCALE = 1.0507009873554804934193349852946
#: An activation applied in place to x, with a scratch buffer t of the same size.
Activation = Callable[[np.ndarray, np.ndarray], None]


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
