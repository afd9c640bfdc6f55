"""The state estimator over recorded bags, and its error against the recorded ground truth.

A bag made with sensors (``generate --sensor-noise``, data/sensorbag.py) holds the robot's
sensor topics and, on ``/fall_predictor/measurement``, the simulator's exact state. Its sensor
messages go, in the order they were received, through
:class:`~fall_predictor.monitor.sensor_pipeline.SensorPipeline`: the same code the live
``state_estimator_node`` runs, so the offline estimates are the live ones. For the error against
the truth the estimator's world frame is aligned with the truth's at its first estimate (the
frame the robot starts in, as any comparison against motion capture aligns it: the truth's
heading, and the horizontal offset of the first estimated CoM); it then runs on the sensors alone.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Optional

import numpy as np

from fall_predictor.profiles.profile import DEFAULT_ROBOT, load_profile
from fall_predictor.data.bagio import BagError, read_trajectory
from fall_predictor.data.sensorbag import read_robot_description, read_sensor_messages
from fall_predictor.monitor.contact_modes import classify_contact_mode
from fall_predictor.monitor.estimator import EstimatorConfig
from fall_predictor.monitor.records import Measurement
from fall_predictor.monitor.robot_description import DescriptionError, SensorLayout
from fall_predictor.monitor.sensor_pipeline import Estimate, PipelineConfig, SensorPipeline

#: Window after the push onset of the post-push statistics [s].
POST_PUSH_WINDOW_S = 0.5
#: JSON names of the compared quantities and their Measurement fields.
QUANTITIES = {'com_m': 'com', 'linear_momentum_kg_m_s': 'lin_mom',
              'angular_momentum_kg_m2_s': 'ang_mom', 'cop_m': 'cop'}


def default_layout(robot: str = DEFAULT_ROBOT) -> SensorLayout:
    """The sensor layout of robot ``robot`` (a profile name or path): soles, IMU frame, foot sensors."""
    return load_profile(robot).sensor_layout()


def run_pipeline(path: str | os.PathLike[str], urdf: Optional[str] = None,
                 config: EstimatorConfig = EstimatorConfig(),
                 layout: Optional[SensorLayout] = None, robot: str = DEFAULT_ROBOT) -> list[Estimate]:
    """Every estimate of a bag's sensor messages, as the live node makes them (``urdf``
    replaces the bag's ``/robot_description``, for recordings without one; ``layout``, else the
    profile of ``robot``, names the soles, the IMU frame and the foot sensors)."""
    bag = Path(path)
    urdf = urdf if urdf is not None else read_robot_description(bag)
    if urdf is None:
        raise BagError(f'{bag}: no /robot_description (was it generated with --sensor-noise?)')
    layout = layout or default_layout(robot)
    try:
        pipeline = SensorPipeline(layout.description(urdf), layout.imu_frame, layout.force_sensors,
                                  PipelineConfig(estimator=config))
    except DescriptionError as error:
        raise BagError(f'{bag}: /robot_description: {error}') from error
    estimates: list[Estimate] = []
    for stream, reading in read_sensor_messages(bag, robot):
        estimates.extend(pipeline.add(stream, reading))
    return estimates + pipeline.flush()


def _stamped(e: Estimate) -> Measurement:
    """The estimate's measurement at its stamp's time (simulation time in generated bags)."""
    return replace(e.measurement, t=e.stamp_ns / 1e9)


@dataclass(frozen=True)
class EstimatedRun:
    """What the estimator made of a bag's sensor topics: the measurements (at their stamps'
    times), and the estimates it refused instead, each as ``(stamp [s], fault)``: a sensor
    missing or out of its bounds, an estimate no humanoid can be in (a fallen robot's CoM
    dead-reckoned below the ground). A refused estimate is a hole in the data, as it is onboard,
    where the node publishes the fault and the monitor a DEGRADED state."""

    measurements: list[Measurement]
    refused: list[tuple[float, str]]


def estimated_run(path: str | os.PathLike[str], config: EstimatorConfig = EstimatorConfig(),
                  urdf: Optional[str] = None, robot: str = DEFAULT_ROBOT) -> EstimatedRun:
    """The state the estimator gives from a bag's sensor topics alone, as the live node runs it:
    default configuration, the world frame the robot starts in, no ground truth; the estimates it
    refused apart (:class:`EstimatedRun`)."""
    measurements: list[Measurement] = []
    refused: list[tuple[float, str]] = []
    for e in run_pipeline(path, urdf, config, robot=robot):
        if e.measurement is None:
            refused.append((e.stamp_ns / 1e9, e.fault))
        else:
            measurements.append(_stamped(e))
    return EstimatedRun(measurements, refused)


def estimated_measurements(path: str | os.PathLike[str], config: EstimatorConfig = EstimatorConfig(),
                           urdf: Optional[str] = None, robot: str = DEFAULT_ROBOT) -> list[Measurement]:
    """The measurements of :func:`estimated_run` (samples without an estimate are left out, as
    the node publishes a fault for them)."""
    return estimated_run(path, config, urdf, robot).measurements


def aligned_config(path: str | os.PathLike[str], urdf: str, truth: dict,
                   config: EstimatorConfig = EstimatorConfig(),
                   robot: str = DEFAULT_ROBOT) -> EstimatorConfig:
    """``config`` with its world frame aligned to the truth's at the first estimate: the truth's
    heading, and the horizontal offset that puts the first estimated CoM on the true one."""
    first_ns = next(r.stamp_ns for stream, r in read_sensor_messages(path) if stream == 'joints')
    first = truth.get(round(first_ns / 1e6))
    config = replace(config, initial_yaw_rad=float(first.heading) if first is not None else 0.0)
    for e in run_pipeline(path, urdf, config, robot=robot)[:50]:
        ref = truth.get(round(e.stamp_ns / 1e6))
        if e.measurement is not None and ref is not None:
            dx, dy = (ref.com - e.measurement.com)[:2]
            return replace(config, initial_xy_m=(config.initial_xy_m[0] + float(dx),
                                                 config.initial_xy_m[1] + float(dy)))
    return config


@dataclass
class BagEstimate:
    """Estimated and true measurements of one bag, paired by time (estimates may be None)."""

    t: np.ndarray
    estimated: list[Optional[Measurement]]
    truth: list[Measurement]


def estimate_bag(path: str | os.PathLike[str], config: EstimatorConfig = EstimatorConfig(),
                 robot: str = DEFAULT_ROBOT) -> BagEstimate:
    """Run the estimator over a bag's sensor topics (robot profile ``robot``); pair each estimate
    with the truth."""
    bag = Path(path)
    urdf = read_robot_description(bag)
    if urdf is None:
        raise BagError(f'{bag}: no /robot_description (was it generated with --sensor-noise?)')
    truth = read_trajectory(bag).measurements or []
    if not truth:
        raise BagError(f'{bag}: no ground truth')
    by_ms = {round(m.t * 1000): m for m in truth}
    t, est, tru = [], [], []
    for e in run_pipeline(bag, urdf, aligned_config(bag, urdf, by_ms, config, robot), robot=robot):
        ref = by_ms.get(round(e.stamp_ns / 1e6))
        if ref is not None:
            t.append(e.stamp_ns / 1e9)
            est.append(None if e.measurement is None else _stamped(e))
            tru.append(ref)
    if not t:
        raise BagError(f'{bag}: no sensor samples')
    return BagEstimate(np.array(t), est, tru)


def contact_mode_or_unclassified(m: Measurement) -> int:
    """The contact mode index of ``m``, or -1 where its contacts cannot be classified (the
    comparison with the truth then counts a disagreement, not an error)."""
    try:
        return classify_contact_mode(m)
    except ValueError:
        return -1


def error_samples(b: BagEstimate, t_push: float) -> dict[str, np.ndarray]:
    """Per-sample errors of one bag (Euclidean norms), the post-push mask, mode agreement."""
    ok = [i for i, m in enumerate(b.estimated) if m is not None]
    out: dict[str, np.ndarray] = {}
    for key, name in QUANTITIES.items():
        out[key] = np.array([np.linalg.norm(getattr(b.estimated[i], name) - getattr(b.truth[i], name))
                             for i in ok])
    t = b.t[ok]
    out['post_push'] = (t >= t_push - 1e-9) & (t <= t_push + POST_PUSH_WINDOW_S + 1e-9)
    out['mode_agree'] = np.array([contact_mode_or_unclassified(b.estimated[i])
                                  == contact_mode_or_unclassified(b.truth[i]) for i in ok])
    return out


def summarise(per_bag: list[dict[str, np.ndarray]]) -> dict:
    """The ``estimation-error`` JSON: per quantity median and p99 over all samples and over the
    post-push windows (NaN errors, e.g. a CoP with no contact on one side, are left out)."""
    result: dict = {}
    post = np.concatenate([b['post_push'] for b in per_bag])
    for key in QUANTITIES:
        e = np.concatenate([b[key] for b in per_bag])
        finite = np.isfinite(e)
        all_e, post_e = e[finite], e[finite & post]

        def stat(x, q):
            return float(np.percentile(x, q)) if len(x) else None
        result[key] = {'median': stat(all_e, 50), 'p99': stat(all_e, 99),
                       'post_push_median': stat(post_e, 50), 'post_push_p99': stat(post_e, 99)}
    agree = np.concatenate([b['mode_agree'] for b in per_bag])
    result['contact_mode_agreement'] = float(agree.mean()) if len(agree) else None
    return result
