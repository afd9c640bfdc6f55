"""The onboard monitor of a robot replayed offline (data/onboard_replay): built as the nodes
build it, and the same alarms as a chain assembled part by part; ``render --model`` marks them."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from fall_predictor import cli
from fall_predictor.data.onboard_replay import first_alarm, onboard_chain
from fall_predictor.monitor.chain import OnboardChain
from fall_predictor.monitor.fall_monitor import EVENT_FALLING, FallenConfig, FallMonitor
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.records import PushSpec
from fall_predictor.monitor.sensor_pipeline import SensorPipeline
from fall_predictor.profiles.profile import load_profile
from fall_predictor.sim.drivers import driver_messages
from fall_predictor.sim.sensors import SensorParams, apply_sensors
from fall_predictor.sim.trajectory import run_trajectory

MODELS = Path(__file__).resolve().parents[1] / 'models'
#: (force [N], direction [deg]) at t = 1 s on the ASIMO-like robot: a fall, then a survived push.
PUSHES = ((420.0, 0.0), (200.0, 45.0))


@pytest.fixture(scope='module')
def runs():
    out = []
    for k, (force_n, angle_deg) in enumerate(PUSHES):
        run = run_trajectory(PushSpec(force_n, angle_deg, 0.1, 1.0), 2.5, record_sensors=True)
        out.append((run, apply_sensors(run.sensor_truths, SensorParams(), seed=k)))
    return out


def part_by_part_alarm_s(samples, model: Path) -> float | None:
    """The reference: the chain assembled from its parts, as the asimo_like robot's nodes are."""
    profile = load_profile('asimo_like')
    lists, metadata = load_model(model)
    layout = profile.sensor_layout()
    settings = metadata.feature_settings
    chain = OnboardChain(SensorPipeline(layout.description(profile.urdf_path.read_text()),
                                        layout.imu_frame, layout.force_sensors),
                         settings, FallMonitor(lists, metadata.recommended_tau_his_s,
                                               FallenConfig(profile.fallen_com_height_m,
                                                            profile.guard_com_height_m),
                                               settings.sample_period_s,
                                               settings.guard_com_height_m, profile.total_mass_kg))
    for stream, reading in driver_messages(samples):
        for out in chain.add(stream, reading):
            if out.event is not None and out.event.kind == EVENT_FALLING:
                return out.stamp_ns / 1e9
    return None


def test_the_replayed_monitor_calls_the_fall_in_time_and_the_survived_push_not(runs):
    model = MODELS / 'default_model.json'
    (fall, fall_samples), (survived, survived_samples) = runs
    assert fall.fallen and not survived.fallen
    alarm = first_alarm(onboard_chain(load_profile('asimo_like'), model), driver_messages(fall_samples))
    assert alarm is not None and 1.0 <= alarm.stamp_s < fall.t_fallen
    assert alarm.stamp_s == pytest.approx(part_by_part_alarm_s(fall_samples, model), abs=1e-9)
    # The model's time to fall comes with it (fitted at its triggers, method §8d).
    assert alarm.time_to_fall_s is not None and 0.0 < alarm.time_to_fall_s < 2.0
    assert first_alarm(onboard_chain(load_profile('asimo_like'), model),
                       driver_messages(survived_samples)) is None
    assert part_by_part_alarm_s(survived_samples, model) is None


def test_the_chain_takes_the_robots_fallen_heights_and_the_models_window():
    profile = load_profile('g1')
    chain = onboard_chain(profile, MODELS / 'g1_attitude_model.json')
    _, metadata = load_model(MODELS / 'g1_attitude_model.json')
    monitor = chain.monitor
    assert monitor.fallen_config == FallenConfig(profile.fallen_com_height_m, profile.guard_com_height_m)
    assert monitor.predictor.tau_his_s == metadata.recommended_tau_his_s
    assert monitor.mass_kg == profile.total_mass_kg


def test_render_marks_the_monitors_alarm_of_the_run_it_shows(runs, tmp_path, capsys):
    out = tmp_path / 'fall.png'
    code = cli.main(['render', '--force', '420', '--angle', '0', '--onset', '1.0', '--before', '0',
                     '--after', '1.0', '--frames', '3', '--model', str(MODELS / 'default_model.json'),
                     '--out', str(out), '--json'])
    assert code == 0
    payload = json.loads(capsys.readouterr().out)
    fall, _ = runs[0]
    assert payload['fallen'] and payload['t_fallen'] == pytest.approx(fall.t_fallen)
    assert 1.0 <= payload['t_alarm'] < payload['t_fallen']
    assert payload['lead_s'] == pytest.approx(payload['t_fallen'] - payload['t_alarm'])
    assert out.stat().st_size > 10_000
