"""The sensor clock steps (an NTP or PTP step on the robot, a simulator reset, a recording that
loops) through the whole onboard chain with the shipped model: a step of the whole stream starts a
new timeline (no FALLING, OK states again after the time rule's confirmation, the latch kept, said
once); a stream stepping alone gives DEGRADED states that say the clocks differ.

The walk and the chain are :mod:`test_onboard_faults`' (an unpushed ASIMO-like walk published as a
robot's drivers do: legs and upper body from two drivers, the IMU and both foot sensors, epoch
stamps, 1 kHz).
"""
from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fall_predictor.monitor.fall_monitor import (EVENT_FALLING, STATUS_DEGRADED, STATUS_OK,
                                                 FallEvent)
from fall_predictor.monitor.timeline import NS_PER_S, TimelineConfig
from test_onboard_faults import EPOCH_NS, FAULT_START, MS, chain, messages  # noqa: F401

MODELS = Path(__file__).resolve().parents[1] / 'models'
STREAMS = ('joints', 'imu', 'l', 'r')
STEP_NS = 10 * NS_PER_S
#: The time rule's confirmation of a step back: its samples are dropped, the last one starts the run.
JUMP_SAMPLES = TimelineConfig().jump_samples


def stepped(messages, step_ns: int, streams=STREAMS, start_ns: int = FAULT_START):
    """The recording with the stamps of ``streams`` moved by ``step_ns`` from ``start_ns`` on (in
    the recording's own time), in the order the drivers published them."""
    return [(s, replace(r, stamp_ns=r.stamp_ns + step_ns)
             if s in streams and r.stamp_ns - EPOCH_NS >= start_ns else r) for s, r in messages]


def run(readings, latched: bool = False):
    c = chain()
    if latched:                                 # a fall already triggered before the step
        c.monitor._latched = True
    outputs, notices = [], []
    for stream, reading in readings:
        outputs += c.add(stream, reading)
        notices += c.pipeline.take_notices()
    outputs += c.flush()
    notices += c.pipeline.take_notices()
    return c, outputs, notices


@pytest.mark.parametrize('step_ns', [-STEP_NS, STEP_NS, -300 * MS],
                         ids=['back 10 s', 'forward 10 s', 'back 0.3 s (a simulator reset)'])
def test_a_step_of_the_whole_stream_starts_a_new_timeline(messages, step_ns: int) -> None:
    c, outputs, notices = run(stepped(messages, step_ns), latched=True)
    assert not [o for o in outputs if o.event is not None and o.event.kind == EVENT_FALLING]
    k = next(i for i in range(1, len(outputs))
             if not 0 < outputs[i].stamp_ns - outputs[i - 1].stamp_ns < 100 * MS)
    before = [o for o in outputs[:k] if o.stamp_ns - EPOCH_NS >= 100 * MS]
    after = outputs[k:]
    assert before and all(o.state.status == STATUS_OK for o in before)
    # Every state of the new timeline is OK: no reading of the old one is matched with it.
    assert after and all(o.state.status == STATUS_OK for o in after), after[0].state.reason
    # The first state comes once the step is confirmed: after JUMP_SAMPLES samples back (the
    # rule's protection against one stray stamp), after 2 forward (the held one and its follower).
    first_ms = (after[0].stamp_ns - EPOCH_NS - step_ns - FAULT_START) / MS
    assert first_ms == (JUMP_SAMPLES - 1 if step_ns < 0 else 1)
    assert c.pipeline.timeline.jumps + c.pipeline.timeline.pauses == 1
    # The latch stays; the history window restarted (the new run's first states are not falling
    # by the window, they cannot be: the walk is not falling); said once, in words.
    assert all(o.state.latched for o in outputs)
    assert len(notices) == 1, notices
    direction = 'back' if step_ns < 0 else 'forward'
    assert notices[0].startswith('/joint_states and /imu/data and /left_foot/wrench and '
                                 f'/right_foot/wrench stamps stepped {direction} '
                                 f'{abs(step_ns) / NS_PER_S:.3f} s')
    assert 'the fall latch kept' in notices[0]


@pytest.mark.parametrize('stream, words', [
    ('imu', r'no /imu/data within 5 ms of /joint_states \(its stamps are (\S+) s behind '
            r'/joint_states: the clocks differ\)'),
    ('l', r'no /left_foot/wrench within 5 ms of /joint_states \(its stamps are (\S+) s behind '
          r'/joint_states: the clocks differ\)'),
    ('joints', r'no /imu/data within 5 ms of /joint_states \(its stamps are (\S+) s ahead of '
               r'/joint_states: the clocks differ\)'),
])
def test_one_stream_stepping_alone_degrades_with_the_reason_never_falls(messages, stream, words
                                                                        ) -> None:
    """Its readings cannot be matched with the others' any more: every sample after the step
    is DEGRADED with the reason in words (never a reading of the old timeline matched with the
    new), never a fall; the step is told once."""
    _, outputs, notices = run(stepped(messages, -STEP_NS, streams=(stream,)))
    assert not [o for o in outputs if o.event is not None and o.event.kind == EVENT_FALLING]
    assert not any(o.state.falling for o in outputs)
    shift = -STEP_NS if stream == 'joints' else 0
    after = [o for o in outputs
             if o.stamp_ns - EPOCH_NS - shift >= FAULT_START + 10 * MS
             and (shift == 0 or o.stamp_ns - EPOCH_NS < 0)]
    assert after and all(o.state.status == STATUS_DEGRADED for o in after)
    offsets_s = [float(re.search(words, o.state.reason).group(1)) for o in after]
    # The other streams' readings lie within a millisecond of the driving ones.
    assert min(offsets_s) >= 9.998 and max(offsets_s) <= 10.001
    assert len(notices) == 1 and 'stepped back 10.000 s' in notices[0], notices


@pytest.mark.parametrize('robot, push', [
    ('asimo_like', (420.0, 0.0, 0.1, 1.6)),
    pytest.param('g1', (180.0, 0.0, 0.1, 1.6), marks=pytest.mark.slow),
])
def test_a_fall_after_a_step_back_is_caught_as_without_it(robot: str, push: tuple) -> None:
    """A pushed walk that falls, its whole sensor stream stepped back 10 s a second before the
    push, each robot with its shipped model: the alarm comes at the same point of the motion as
    without the step (the step only costs the time rule's confirmation samples and the history
    window it restarts), where the readings of the old timeline used to blind the monitor."""
    from fall_predictor.monitor.chain import OnboardChain
    from fall_predictor.monitor.fall_monitor import FallenConfig, FallMonitor
    from fall_predictor.monitor.model_file import load_model
    from fall_predictor.monitor.records import PushSpec
    from fall_predictor.monitor.sensor_pipeline import SensorPipeline
    from fall_predictor.profiles.profile import load_profile
    from fall_predictor.sim.drivers import DriverTiming, driver_messages
    from fall_predictor.sim.sensors import SensorParams, apply_sensors
    from fall_predictor.sim.trajectory import run_trajectory

    profile = load_profile(robot)
    from fall_predictor.sim.world import make_world
    result = run_trajectory(PushSpec(*push), 3.4, record_sensors=True, world=make_world(profile))
    assert result.fallen
    timing = DriverTiming.robot(1000.0)
    recording = list(driver_messages(apply_sensors(result.sensor_truths, SensorParams(), seed=0,
                                                   profile=profile), timing))

    def alarm_s(readings, step_ns: int) -> float:
        lists, metadata = load_model(MODELS / profile.model)
        settings = metadata.feature_settings
        layout = profile.sensor_layout()
        pipeline = SensorPipeline(layout.description(profile.urdf_xml()), layout.imu_frame,
                                  layout.force_sensors)
        monitor = FallMonitor(lists, metadata.recommended_tau_his_s,
                              FallenConfig(profile.fallen_com_height_m, profile.guard_com_height_m),
                              settings.sample_period_s, settings.guard_com_height_m,
                              profile.total_mass_kg)
        c = OnboardChain(pipeline, settings, monitor)
        outputs = [o for s, r in readings for o in c.add(s, r)] + c.flush()
        alarm = next(o for o in outputs if o.event is not None and o.event.kind == EVENT_FALLING)
        return (alarm.stamp_ns - timing.clock_offset_ns - step_ns) / NS_PER_S
    clean_s = alarm_s(recording, 0)
    offset = timing.clock_offset_ns
    stepped_back = [(s, replace(r, stamp_ns=r.stamp_ns - STEP_NS)
                     if r.stamp_ns - offset >= 600 * MS else r) for s, r in recording]
    step_s = alarm_s(stepped_back, -STEP_NS)
    assert clean_s < result.t_fallen - 0.3
    assert step_s == pytest.approx(clean_s, abs=0.002)


def test_the_latch_survives_a_new_run_and_only_reset_undoes_it() -> None:
    from fall_predictor.monitor.fall_monitor import EVENT_RESET
    c = chain()
    c.monitor._latched = True
    c.monitor.new_run()
    assert c.monitor.latched
    assert c.monitor.reset() == FallEvent(EVENT_RESET) and not c.monitor.latched
    assert np.isnan(FallEvent(EVENT_RESET).time_to_fall_s)
