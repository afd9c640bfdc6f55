"""The samples of a trajectory the estimator or the feature extractor refuses: holes in the data,
counted per trajectory (:mod:`fall_predictor.data.dataset`'s module docs), as the onboard chain
leaves them (``monitor/chain.py``: a DEGRADED state, no prediction)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterable, Sequence

import numpy as np

from fall_predictor.monitor.features import FeatureSettings
from fall_predictor.monitor.plausibility import ImplausibleSample
from fall_predictor.monitor.records import Measurement


@dataclass(frozen=True)
class RefusedSamples:
    """The samples of one trajectory left out as holes (module docs)."""

    estimator: int = 0              #: estimates the state estimator refused (a fault instead)
    features: int = 0               #: measurements the feature extractor refused
    first: str = ''                 #: the first of them: its time [s] and why

    @property
    def total(self) -> int:
        return self.estimator + self.features

    def to_json(self) -> dict[str, Any]:
        return {'estimator': self.estimator, 'features': self.features, 'total': self.total,
                'first': self.first}

    @classmethod
    def summed(cls, refused: Iterable['RefusedSamples']) -> 'RefusedSamples':
        """The counts of several trajectories' refused samples added up (``first``: none)."""
        refused = list(refused)
        return cls(sum(r.estimator for r in refused), sum(r.features for r in refused))


def usable_features(measurements: Sequence[Measurement], settings: FeatureSettings = FeatureSettings(),
                    attitude: bool = True
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[tuple[float, str]]]:
    """The features of the measurements the extractor accepts, as the onboard chain computes them
    (``monitor/chain.py``): one :class:`~fall_predictor.monitor.features.FeatureExtractor` over
    the whole recording; a measurement it refuses (ValueError, among them
    :class:`~fall_predictor.monitor.plausibility.ImplausibleSample`) leaves it unchanged and is a
    hole. Returns the indices of the accepted measurements, their inputs (N, 15), or (N, 19)
    with ``attitude``, their contact modes, and the refused ones as ``(t [s], why)``."""
    extractor = settings.extractor(attitude=attitude)
    kept: list[int] = []
    rows: list[np.ndarray] = []
    modes: list[int] = []
    refused: list[tuple[float, str]] = []
    for i, m in enumerate(measurements):
        try:
            x, mode = extractor.update(m)
        except (ValueError, ImplausibleSample) as error:
            refused.append((float(m.t), f'measurement refused: {error}'))
            continue
        kept.append(i)
        rows.append(x)
        modes.append(mode)
    X = np.array(rows).reshape(len(rows), extractor.n_outputs)
    return np.array(kept, dtype=np.int64), X, np.array(modes, dtype=np.int64), refused


def _refused_arrays(estimator: list[tuple[float, str]], features: list[tuple[float, str]]
                    ) -> dict[str, np.ndarray]:
    """The cache entry's record of the refused samples (:class:`RefusedSamples`)."""
    first = min(estimator + features, default=None, key=lambda refusal: refusal[0])
    return {'refused_estimator': np.asarray(len(estimator)),
            'refused_features': np.asarray(len(features)),
            'refused_first': np.asarray('' if first is None else f'{first[0]:.3f} s: {first[1]}')}


def refused_samples(arrays: dict[str, np.ndarray]) -> RefusedSamples:
    """The refused samples a cache entry records (none in entries of other derived data)."""
    if 'refused_estimator' not in arrays:
        return RefusedSamples()
    return RefusedSamples(int(arrays['refused_estimator']), int(arrays['refused_features']),
                          str(arrays['refused_first']))
