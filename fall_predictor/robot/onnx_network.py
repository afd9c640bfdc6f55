"""An ONNX policy network in onnxruntime (:class:`OnnxNetwork`; imported only for an ONNX
policy)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fall_predictor.robot.numpy_networks import _copy_in

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
