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

The numpy networks are in :mod:`~fall_predictor.robot.numpy_networks`, their recognition in a
TorchScript archive in :mod:`~fall_predictor.robot.torchscript_networks`, the ONNX runner in
:mod:`~fall_predictor.robot.onnx_network`.
"""
from __future__ import annotations

from pathlib import Path
from typing import Protocol, Union

import numpy as np

from fall_predictor.robot.torchscript import read_torchscript
from fall_predictor.robot.torchscript_networks import network_from_module


class PolicyNetwork(Protocol):
    """What :func:`load_network` returns."""

    input_size: int
    output_size: int
    recurrent: bool

    def reset(self) -> None: ...

    def __call__(self, obs: np.ndarray) -> np.ndarray: ...

    def describe(self) -> str: ...


def load_network(path: Union[str, Path]) -> PolicyNetwork:
    """The policy network of a ``.pt`` (TorchScript, run in numpy) or ``.onnx`` file."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f'{path}: no such policy file')
    if path.suffix == '.onnx':
        from fall_predictor.robot.onnx_network import OnnxNetwork
        return OnnxNetwork(path)
    if path.suffix in ('.pt', '.pth', '.jit', '.zip'):
        return network_from_module(read_torchscript(path).module, path.name)
    raise ValueError(f'{path}: unknown policy file type {path.suffix!r} (expected .pt (TorchScript) '
                     f'or .onnx)')
