#!/usr/bin/env python3
"""CPU time per sample of each onboard stage, without ROS: what one 1 kHz sample costs the
robot's computer before any message passing.

For each robot (``--robot``, repeatable; default the shipped robot and the G1), a pushed run is
simulated with sensors, its readings are turned into the messages the robot's drivers publish
(:func:`~fall_predictor.sim.drivers.driver_messages`, the simulator's timing) and fed through
the onboard chain (:class:`~fall_predictor.monitor.chain.OnboardChain`, what ``fall_monitor
--estimator`` runs) with the robot's shipped model; each stage's inputs are recorded, then each
stage is run alone over them:

* ``estimator_us``: :meth:`StateEstimator.update`;
* ``features_us``: :meth:`FeatureExtractor.update`;
* ``predictor_us``: :meth:`FallMonitor.step` (decision lists, history window, trigger, direction,
  time to fall);
* ``sensor_input_us``: the rest of the input path per estimate: the readings into the sensor
  buffers, the time rule, the synchronised sample (the whole :class:`SensorPipeline` over the
  messages, less the estimator).

``cpu_mean``: CPU time of a whole pass divided by its samples (``time.thread_time_ns``, read
twice per pass: reading that clock costs microseconds in a VM, too much to read per call), the
least of ``--repeats`` passes; median, p90, p99: per-call wall time (``time.perf_counter_ns``,
cheap to read), all passes. The aims: estimator <= 50 us, features + predictor <= 20 us per
sample (``cpu_mean``). Prints one JSON object; ``--out`` writes it.

    python benchmarks/bench_onboard_cost.py --out docs/monitor/onboard_cost.json
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
from functools import partial
from pathlib import Path

import numpy as np

from fall_predictor.monitor.chain import OnboardChain, base_tilt_rad
from fall_predictor.monitor.fall_monitor import FallenConfig, FallMonitor
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.records import PushSpec
from fall_predictor.monitor.sensor_pipeline import SensorPipeline
from fall_predictor.profiles.profile import load_profile
from fall_predictor.sim.drivers import driver_messages
from fall_predictor.sim.sensors import SensorParams, apply_sensors
from fall_predictor.sim.trajectory import run_trajectory
from fall_predictor.sim.world import make_world

from portable_paths import portable             # noqa: E402  (benchmarks/ is on the path)

MODELS = Path(__file__).resolve().parents[1] / 'models'
AIMS_US = {'estimator_us': 50.0, 'features_plus_predictor_us': 20.0}


def summary(us: np.ndarray) -> dict[str, float]:
    return {'median': round(float(np.median(us)), 1), 'p90': round(float(np.percentile(us, 90)), 1),
            'p99': round(float(np.percentile(us, 99)), 1), 'mean': round(float(np.mean(us)), 1)}


def messages_of(profile, duration_s: float, push: PushSpec, seed: int) -> list:
    run = run_trajectory(push, duration_s, record_sensors=True, world=make_world(profile))
    samples = apply_sensors(run.sensor_truths, SensorParams(), seed=seed, profile=profile)
    return list(driver_messages(samples))


def chain_for(profile, model: Path | None = None) -> OnboardChain:
    lists, metadata = load_model(model or MODELS / profile.model)
    settings = metadata.feature_settings
    layout = profile.sensor_layout()
    pipeline = SensorPipeline(layout.description(profile.urdf_xml()), layout.imu_frame,
                              layout.force_sensors)
    fallen = FallenConfig(profile.fallen_com_height_m, profile.guard_com_height_m)
    monitor = FallMonitor(lists, metadata.recommended_tau_his_s, fallen, settings.sample_period_s,
                          settings.guard_com_height_m, profile.total_mass_kg, metadata.time_to_fall,
                          fall_direction=metadata.fall_direction)    # as the predictor node
    return OnboardChain(pipeline, settings, monitor)


def record_stages(chain: OnboardChain, messages: list) -> dict[str, list]:
    """Each stage's inputs, recorded from one pass of the chain over the messages."""
    estimator = chain.pipeline.estimator
    samples, update = [], estimator.update

    def recording_update(sample):
        samples.append(sample)
        return update(sample)
    estimator.update = recording_update
    measurements, features, tilts, times = [], [], [], []
    for stream, reading in messages:
        for out in chain.add(stream, reading):
            if out.measurement is not None:
                measurements.append(out.measurement)
    estimator.update = update
    extractor = chain.extractor
    extractor.reset()
    for m in measurements:
        features.append(extractor.update(m))
        tilts.append(base_tilt_rad(m.torso_rotation))
        times.append(m.t)
    return {'samples': samples, 'measurements': measurements, 'features': features,
            'tilts': tilts, 'times': times}


def time_stage(calls, reset) -> tuple[np.ndarray, float]:
    """Per-call wall time [us] (perf_counter_ns: cheap to read, so the clock itself costs little)
    and the mean CPU time per call [us] of the whole pass (one thread_time_ns pair)."""
    reset()
    per_call = np.empty(len(calls))
    clock = time.perf_counter_ns
    c0 = time.thread_time_ns()
    for i, call in enumerate(calls):
        w0 = clock()
        call()
        per_call[i] = clock() - w0
    cpu_mean_us = (time.thread_time_ns() - c0) / len(calls) / 1e3
    return per_call / 1e3, cpu_mean_us


def time_chain(profile, messages: list, model: Path | None = None
               ) -> dict[str, tuple[np.ndarray, float]]:
    """Per stage: per-call times [us] and mean CPU per sample [us] (module docstring)."""
    chain = chain_for(profile, model)
    rec = record_stages(chain, messages)
    estimator, extractor, monitor = chain.pipeline.estimator, chain.extractor, chain.monitor
    out = {}
    out['estimator_us'] = time_stage([partial(estimator.update, s) for s in rec['samples']],
                                     estimator.reset)
    out['features_us'] = time_stage([partial(extractor.update, m) for m in rec['measurements']],
                                    extractor.reset)
    out['predictor_us'] = time_stage(
        [partial(monitor.step, t, x, mode, tilt)
         for t, (x, mode), tilt in zip(rec['times'], rec['features'], rec['tilts'])],
        monitor.new_run)
    # The whole input path per estimate (readings into the buffers, the time rule, the
    # synchronised sample, the estimator), less the estimator: the sensor input's own cost.
    pipeline = chain_for(profile, model).pipeline
    c0 = time.thread_time_ns()
    n = sum(len(pipeline.add(stream, reading)) for stream, reading in messages)
    whole_us = (time.thread_time_ns() - c0) / n / 1e3
    out['sensor_input_us'] = (None, whole_us - out['estimator_us'][1])
    return out


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--robot', action='append', help='robot profile (repeatable)')
    parser.add_argument('--duration', type=float, default=4.0, help='simulated seconds')
    parser.add_argument('--repeats', type=int, default=3, help='passes over the recording')
    parser.add_argument('--model', type=Path, default=None,
                        help="model file instead of the robot profile's shipped one")
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    result = {'aims_us': AIMS_US, 'robots': {}, 'python': platform.python_version(),
              'model': str(args.model) if args.model else 'each robot profile\'s shipped model',
              'machine': platform.machine(), 'cores': os.cpu_count()}
    for name in args.robot or ['asimo_like', 'g1']:
        profile = load_profile(name)
        push = PushSpec(0.6 * profile.push_force_n[1], 90.0, 0.1, 1.0)
        messages = messages_of(profile, args.duration, push, seed=0)
        runs = [time_chain(profile, messages, args.model) for _ in range(args.repeats)]
        row = {}
        for stage in runs[0]:
            cpu = min(r[stage][1] for r in runs)           # the least disturbed pass
            row[stage] = {'cpu_mean': round(cpu, 1)}
            if runs[0][stage][0] is not None:
                row[stage].update(summary(np.concatenate([r[stage][0] for r in runs])))
        row['total_cpu_mean_us'] = round(sum(row[s]['cpu_mean'] for s in runs[0]), 1)
        row['estimates'] = len(runs[0]['estimator_us'][0])
        est = row['estimator_us']['cpu_mean']
        fp = row['features_us']['cpu_mean'] + row['predictor_us']['cpu_mean']
        row['estimator_aim_met'] = bool(est <= AIMS_US['estimator_us'])
        row['features_plus_predictor_cpu_mean_us'] = round(fp, 1)
        row['features_plus_predictor_aim_met'] = bool(fp <= AIMS_US['features_plus_predictor_us'])
        result['robots'][name] = row
    result['load_average'] = os.getloadavg()
    text = json.dumps(portable(result), indent=1)   # no machine path in a committed file
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + '\n')
    print(text)
    return result


if __name__ == '__main__':
    main()
