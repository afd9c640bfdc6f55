"""Helpers of the node and bring-up tests (no tests here).

* a per-process ROS domain (from the pid) with localhost-only discovery, so concurrent test
  runs and other ROS systems on the machine never meet;
* a real model file, hand-built: falling when the horizontal linear momentum exceeds 25 kg m/s
  in any direction of the heading frame (walking stays below 10 kg m/s; a 45 N s push exceeds
  25 kg m/s within the push, about 1 s before the robot is fallen);
* an rclpy context on such a domain.

The tests' own ROS node is the package's :class:`fall_predictor.ros.observer.Observer`, the
bring-up's.
"""
from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import rclpy

from fall_predictor.monitor.boosted_trees import BoostedTrees
from fall_predictor.monitor.decision_list import Condition, DecisionList, PerModeDecisionLists, Rule
from fall_predictor.monitor.model_file import ModelMetadata, save_model
from fall_predictor.monitor.records import FALLING, FEATURE_NAMES, N_CONTACT_MODES
from fall_predictor.monitor.time_to_fall import RegressionTree

#: Momentum threshold of the test model [kg m/s].
MOMENTUM_THRESHOLD = 25.0
#: History window recommended by the test model [s].
MODEL_TAU_HIS_S = 0.01


#: Largest ROS domain id Fast DDS accepts: above it the port numbers overflow and Fast DDS
#: ends the whole process with exit(1), without a Python exception.
MAX_DOMAIN_ID = 232


def test_domain_id(offset: int) -> int:
    """A ROS domain id for this test run: 1..70 from the run plus ``offset`` (one per test module,
    0 <= offset < MAX_DOMAIN_ID), wrapped into 1..MAX_DOMAIN_ID; distinct offsets give distinct
    ids. The run's part is the pid, or under pytest-xdist the run's id, which every worker shares:
    the workers run whole modules (``--dist loadfile``), each on its own offsets, so two workers
    never share a domain, and two runs on one machine rarely do."""
    if not 0 <= offset < MAX_DOMAIN_ID:
        raise ValueError(f'offset must be in [0, {MAX_DOMAIN_ID}), got {offset}')
    return 1 + (_run_part() + offset) % MAX_DOMAIN_ID


def _run_part() -> int:
    run = os.environ.get('PYTEST_XDIST_TESTRUNUID')
    return int(run[:8], 16) % 70 if run else os.getpid() % 70


test_domain_id.__test__ = False        # a helper, not a test


def write_momentum_model(path: Path) -> Path:
    """Save the hand-built momentum model (every contact mode) with ``save_model``."""
    x, y = FEATURE_NAMES.index('lin_mom_x'), FEATURE_NAMES.index('lin_mom_y')
    rules = tuple(Rule((Condition(feature, op, threshold),), FALLING)
                  for feature in (x, y)
                  for op, threshold in (('>', MOMENTUM_THRESHOLD), ('<=', -MOMENTUM_THRESHOLD)))
    lists = PerModeDecisionLists(tuple(DecisionList(rules) for _ in range(N_CONTACT_MODES)))
    save_model(path, lists, ModelMetadata(
        tau_plus_s=0.0, balanced_weight=4.0, falling_weight=1.0, learner_name='hand-built',
        learner_params={'momentum_threshold_kg_m_s': MOMENTUM_THRESHOLD},
        dataset_fingerprint='none', recommended_tau_his_s=MODEL_TAU_HIS_S))
    return path


def write_boosted_model(path: Path) -> Path:
    """A boosted-trees model, one stump per contact mode: score -1 + 2.5 when the forward momentum
    exceeds MOMENTUM_THRESHOLD, else -1 - 0.5; falling above decision threshold 1.0."""
    x = FEATURE_NAMES.index('lin_mom_x')
    stump = RegressionTree((x, -1, -1), (MOMENTUM_THRESHOLD, 0.0, 0.0), (1, -1, -1), (2, -1, -1),
                           (0.0, -0.5, 2.5))
    trees = BoostedTrees((stump,), bias=-1.0, decision_threshold=1.0)
    save_model(path, PerModeDecisionLists((trees,) * N_CONTACT_MODES), ModelMetadata(
        tau_plus_s=0.0, balanced_weight=4.0, falling_weight=1.0, learner_name='hand-built',
        learner_params={}, dataset_fingerprint='none', recommended_tau_his_s=MODEL_TAU_HIS_S))
    return path


@contextmanager
def ros_context(domain_id: int) -> Iterator[rclpy.Context]:
    """An initialised rclpy context on ``domain_id`` with localhost-only discovery."""
    saved = os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    context = rclpy.Context()
    try:
        rclpy.init(context=context, domain_id=domain_id)
    finally:
        if saved is None:
            os.environ.pop('ROS_AUTOMATIC_DISCOVERY_RANGE')
        else:
            os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = saved
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)
