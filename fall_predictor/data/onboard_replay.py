"""The whole onboard monitor of a robot, offline: its profile and a model file in, a replay of
sensor messages through it out.

:func:`onboard_chain` builds the :class:`~fall_predictor.monitor.chain.OnboardChain` that
``fall_monitor --estimator`` runs on robot ``profile`` with a model (the robot's layout and URDF,
the model's feature settings, window, time to fall and direction, the profile's fallen heights
and mass), as the live nodes configure it; :func:`first_alarm` replays messages through it and
gives the first FALLING event. Tools that ask "when would the monitor have called it?" (render,
benchmarks, scripts) use these, so the answer is the live chain's.
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from fall_predictor.monitor.chain import OnboardChain, Reading
from fall_predictor.monitor.fall_monitor import EVENT_FALLING, FallenConfig, FallMonitor
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.sensor_pipeline import PipelineConfig, SensorPipeline
from fall_predictor.profiles.profile import RobotProfile


def onboard_chain(profile: RobotProfile, model: str | Path, urdf: Optional[str] = None,
                  driving_joints: tuple[str, ...] = ()) -> OnboardChain:
    """The onboard chain of ``profile``'s robot running the model file ``model`` at its stored
    window; ``urdf`` is the robot description (default: the profile's), ``driving_joints`` as the
    estimator node's parameter. Raises ModelFileError for a model that cannot be used."""
    lists, metadata = load_model(model)
    settings = metadata.feature_settings
    layout = profile.sensor_layout()
    pipeline = SensorPipeline(layout.description(urdf if urdf is not None else profile.urdf_xml()),
                              layout.imu_frame, layout.force_sensors,
                              config=PipelineConfig(driving_joints=tuple(driving_joints)))
    monitor = FallMonitor(lists, metadata.recommended_tau_his_s or 0.0,
                          FallenConfig(profile.fallen_com_height_m, profile.guard_com_height_m),
                          settings.sample_period_s, settings.guard_com_height_m,
                          profile.total_mass_kg, metadata.time_to_fall,
                          fall_direction=metadata.fall_direction)
    return OnboardChain(pipeline, settings, monitor)


@dataclass(frozen=True)
class Alarm:
    """The monitor's first FALLING event of a replay."""

    stamp_s: float                           #: its sample's stamp [s]
    time_to_fall_s: Optional[float]          #: the time to fall it predicted [s]


def first_alarm(chain: OnboardChain, messages: Iterable[tuple[str, Reading]]) -> Optional[Alarm]:
    """The first FALLING event of ``messages`` ((stream, reading) in arrival order) through
    ``chain``, or None when the monitor never called a fall."""
    def alarm(outputs) -> Optional[Alarm]:
        for out in outputs:
            if out.event is not None and out.event.kind == EVENT_FALLING:
                ttf = out.state.time_to_fall_s
                return Alarm(out.stamp_ns / 1e9, float(ttf) if math.isfinite(ttf) else None)
        return None

    for stream, reading in messages:
        found = alarm(chain.add(stream, reading))
        if found is not None:
            return found
    return alarm(chain.flush())


# -- one run two ways: the standard sensor topics, and a Unitree humanoid's lowstate ---------------
@dataclass(frozen=True)
class Replay:
    """What the monitor said over one replay: the sample index of its first FALLING event (None:
    no alarm), and each sample's status and reason, in order."""

    alarm_index: Optional[int]
    statuses: tuple[int, ...]
    reasons: tuple[str, ...]


def replay(chain: OnboardChain, messages: Iterable[tuple[str, Reading]],
           index_of_stamp: dict[int, int]) -> Replay:
    """Every state of ``messages`` through ``chain``; the alarm's sample from its stamp
    (``index_of_stamp``: the sample index of each driving stamp)."""
    outputs = []
    for stream, reading in messages:
        outputs.extend(chain.add(stream, reading))
    outputs.extend(chain.flush())
    alarm = next((index_of_stamp[o.stamp_ns] for o in outputs
                  if o.event is not None and o.event.kind == EVENT_FALLING), None)
    return Replay(alarm, tuple(o.state.status for o in outputs), tuple(o.state.reason for o in outputs))


def standard_messages(readings, imu_frame: str, clock_ns: int
                      ) -> tuple[list[tuple[str, Reading]], dict[int, int]]:
    """A run's readings as ``joint_states`` and ``imu/data`` stamped on a ROS clock that read
    ``clock_ns`` at the run's start (joints first, the IMU at the same stamp), and the sample
    index of each stamp."""
    from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading
    messages, index = [], {}
    for k, r in enumerate(readings):
        stamp = clock_ns + round(r.t * 1e9)
        index[stamp] = k
        messages.append(('joints', JointStateReading(stamp, r.joint_names, r.q, r.dq, r.tau)))
        messages.append(('imu', ImuReading(stamp, imu_frame, r.imu_quat_xyzw, r.gyro_rad_s,
                                           r.accel_m_s2)))
    return messages, index


def lowstate_messages(records, converter) -> tuple[list[tuple[str, Reading]], dict[int, int]]:
    """LowState ``records`` ((receive time [ns], record), in arrival order) through
    ``converter`` (:class:`~fall_predictor.monitor.lowstate.LowStateConverter`), as the estimator
    node takes them, and the sample index of each stamp it gave."""
    messages, index = [], {}
    for k, (receive_ns, record) in enumerate(records):
        sample = converter.convert(record, receive_ns)
        if sample is not None:
            index[sample.stamp_ns] = k
            messages.append(('lowstate', sample))
    return messages, index
