"""Shared fixtures: a simulator per test; a small generated dataset per test session."""
from pathlib import Path

import pytest

from fall_predictor.sim.simulator import Simulator

#: A small dataset generated once per test session with the real generator (seed chosen so
#: that it holds both outcomes). Horizon shortened to keep the suite fast.
SMALL_DATASET_TRAJECTORIES = 8
SMALL_DATASET_SEED = 3
SMALL_DATASET_HORIZON_S = 2.5


@pytest.fixture
def sim():
    simulator = Simulator()
    yield simulator
    simulator.close()


@pytest.fixture(scope='session')
def small_dataset(tmp_path_factory) -> Path:
    """Directory of a generated 8-trajectory dataset (bags, index, no feature cache yet)."""
    from fall_predictor.data.generation import GenerationConfig, generate_dataset

    out = tmp_path_factory.mktemp('dataset') / 'small'
    config = GenerationConfig(seed=SMALL_DATASET_SEED, horizon_after_push_s=SMALL_DATASET_HORIZON_S,
                              pre_push_s=0.5)
    generate_dataset(out, SMALL_DATASET_TRAJECTORIES, SMALL_DATASET_SEED, jobs=1, config=config,
                     progress=False)
    return out
