"""Datasets made from recorder_node bags (data/recording_import.py ``import_recordings``): the falls are
found with the recorded robot's own fallen height, not another robot's."""
from __future__ import annotations

import json

import numpy as np
import pytest

from fall_predictor.data.bag_writer import BagWriter
from fall_predictor.data.recording_import import import_recordings
from fall_predictor.monitor.records import Measurement
from fall_predictor.profiles.profile import DEFAULT_ROBOT, load_profile

#: Where the recorded G1 ends: below its profile's fallen height (0.38 m), above the ASIMO-like
#: robot's (0.33 m).
G1_END_HEIGHT_M = 0.378


def _sample(t: float, height_m: float) -> Measurement:
    """A robot standing on both soles with its CoM at ``height_m`` (the recorder's measurement)."""
    left = np.array([[0.1, 0.15, 150.0], [-0.1, 0.15, 150.0]])
    right = np.array([[0.1, -0.15, 150.0], [-0.1, -0.15, 150.0]])
    return Measurement(t=t, com=np.array([0.0, 0.0, height_m]), lin_mom=np.zeros(3),
                       ang_mom=np.zeros(3), heading=0.0, cop=np.zeros(3), left_contacts=left,
                       right_contacts=right, left_foot=np.array([0.0, 0.15, 0.0]),
                       right_foot=np.array([0.0, -0.15, 0.0]), non_foot_contact=False)


@pytest.fixture(scope='module')
def g1_bag(tmp_path_factory):
    """A G1 walking at 0.68 m, pushed at 1 s, sinking to 0.378 m at 2 s (a fall that ends on its
    knees and hands: below the G1's fallen height, above the ASIMO-like robot's)."""
    bag = tmp_path_factory.mktemp('recorded') / 'run_0'
    t = np.arange(0.0, 2.5, 0.002)
    height = np.interp(t, [0.0, 1.2, 2.0, 2.5], [0.68, 0.68, G1_END_HEIGHT_M, G1_END_HEIGHT_M])
    with BagWriter(bag) as writer:
        for ti, zi in zip(t, height):
            writer.write_measurement(_sample(float(ti), float(zi)))
        writer.write_push(1.0, [300.0, 0.0, 0.0])
    return bag


def test_a_g1_recording_is_labelled_with_the_g1s_fallen_height(g1_bag, tmp_path):
    assert load_profile('g1').fallen_com_height_m > G1_END_HEIGHT_M
    report = import_recordings([g1_bag], tmp_path / 'g1', robot='g1')
    [row] = report.rows
    assert row.fallen
    # Where the CoM crosses 0.38 m on its way from 0.68 m (1.2 s) to 0.378 m (2.0 s).
    assert row.t_fallen == pytest.approx(1.2 + 0.8 * (0.68 - 0.38) / (0.68 - G1_END_HEIGHT_M), abs=0.003)
    manifest = json.loads((tmp_path / 'g1' / 'dataset.json').read_text())
    assert manifest['robot']['name'] == 'g1'


def test_the_same_recording_as_the_default_robots_is_not_fallen(g1_bag, tmp_path):
    """What import-bags did for every robot before it took --robot's fallen height."""
    assert load_profile(DEFAULT_ROBOT).fallen_com_height_m < G1_END_HEIGHT_M
    [row] = import_recordings([g1_bag], tmp_path / 'default').rows
    assert not row.fallen and row.t_fallen is None
