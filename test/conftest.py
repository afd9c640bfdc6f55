"""Shared fixtures: a simulator per test, closed afterwards."""
import pytest

from fall_predictor.simulator import Simulator


@pytest.fixture
def sim():
    simulator = Simulator()
    yield simulator
    simulator.close()
