"""Shared fixtures: a simulator per test; a small generated dataset per test session. The test
tiers: ``pytest -m "not slow"`` is the fast tier (pure logic and physics oracles, no DDS, no
cluster, no long simulation; under 2 minutes); the full suite (``scripts/test.sh``) runs all."""
import os
from pathlib import Path

import pytest

# One thread per process for OpenMP and BLAS (scikit-learn's boosted trees, numpy), here and in the
# node processes the DDS tests start: on two cores shared by a test and its nodes, OpenMP threads
# that spin for a core another process holds made a 1 s boosted-trees fit take 5-48 s. Fits are
# the same with one thread (the histograms are summed per feature).
os.environ['OMP_NUM_THREADS'] = '1'
import threadpoolctl  # noqa: E402

threadpoolctl.threadpool_limits(1)

#: Modules of the slow tier: those that start ROS 2 nodes over DDS, a Dask cluster, or simulate
#: for tens of seconds (their own names say which).
SLOW_MODULES = frozenset({
    # DDS: nodes, bring-up, recorders, the monitor's contract, replay over DDS
    'test_bringup', 'test_nodes_pipeline', 'test_nodes_units', 'test_monitor_contract',
    'test_state_estimator_node', 'test_robot_replay', 'test_recorder_crash', 'test_recorder_repair',
    'test_recorder_node', 'test_ros_fall_monitor', 'test_lifecycle', 'test_ros_clock_steps',
    'test_markers', 'test_ros_common', 'test_ros_qos', 'test_launch_files',
    'test_ros_policy_controller', 'test_bringup_policy', 'test_lowstate_node',
    # a Dask cluster
    'test_cluster',
    # long simulations: controllers and stabilizer over pushes, the G1, rates, imports, CLI runs
    'test_stabilizer', 'test_controllers', 'test_g1', 'test_robot_rates', 'test_robot_import',
    'test_cli', 'test_dataset', 'test_state_source', 'test_estimation_cli', 'test_simulator',
    'test_team_model', 'test_onboard_replay', 'test_lowstate_replay', 'test_generate_stop',
    'test_check_runs', 'test_disturbance_physics', 'test_disturbance_generation', 'test_randomization',
})


def pytest_collection_modifyitems(config, items):
    for item in items:
        if Path(str(item.fspath)).stem in SLOW_MODULES:
            item.add_marker(pytest.mark.slow)

from fall_predictor.sim.pybullet_world import PybulletWorld

#: A small dataset generated once per test session with the real generator (seed chosen so
#: that it holds both outcomes). Horizon shortened to keep the suite fast.
SMALL_DATASET_TRAJECTORIES = 8
SMALL_DATASET_SEED = 3
SMALL_DATASET_HORIZON_S = 2.5


@pytest.fixture
def sim():
    simulator = PybulletWorld()
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
