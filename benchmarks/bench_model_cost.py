#!/usr/bin/env python3
"""The onboard cost of every shipped model, in one process, against one reference model: what each
model card says a sample costs (``scripts/model_cards.py`` reads the JSON this writes).

Per robot of the cards (``models/cards.yaml``), one pushed run is simulated with sensors and turned
into its drivers' messages (``bench_onboard_cost.py``'s :func:`messages_of`: a push of 0.6 of the
robot's default controller's push range, sideways, 1 s in); each model runs the onboard chain over
its robot's messages once (:func:`record_stages`), and then its stages are timed alone over the
recorded inputs, round-robin over the models so that a change in the machine's speed falls on all
of them alike; each figure is the least of ``--repeats`` rounds (CPU time of a whole pass over the
samples divided by their count, ``time.thread_time_ns``):

* ``features_plus_predictor_us``: :meth:`FeatureExtractor.update` + :meth:`FallMonitor.step`
  with the model's lists or trees, history window, trigger, direction and time to fall: what
  the model costs per sample (the features differ by model: the attitude's inputs);
* ``estimator_us``: :meth:`StateEstimator.update` on the model's robot (one per robot: it does not
  depend on the model; foot F/T, or the efforts' wrench solve without it);
* ``ratio_to_reference``: each figure over the reference model's (``--reference``, the ASIMO-like
  robot's default) in the same round: comparable across days of a VM whose speed varies;
* ``policies``: each learned controller's network call (µs per call, the median of
  ``--policy-calls`` calls on observations of the sensor model's scale) where a profile walks
  with one: the robot's controller cost, beside the monitor's.

    python benchmarks/bench_model_cost.py --out docs/monitor/model_cost.json
"""
from __future__ import annotations

import argparse
import os
import platform
import time
from functools import partial
from pathlib import Path

import numpy as np
import yaml

from fall_predictor.monitor.records import PushSpec
from fall_predictor.profiles.profile import load_profile
from fall_predictor.robot.networks import load_network
from fall_predictor.robot.policy_config import load_policy_config

from bench_onboard_cost import chain_for, messages_of, record_stages  # noqa: E402  (benchmarks/ on the path)
from portable_paths import write_json                                   # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / 'models'


def shipped_models() -> dict[str, str]:
    """Model file name -> its robot profile, from the cards."""
    cards = yaml.safe_load((MODELS / 'cards.yaml').read_text())
    return {name: entry['robot'] for name, entry in cards.items()}


def push_for(profile) -> PushSpec:
    controller = profile.controller_profile()
    high = (controller.push_force_n if controller is not None else profile.push_force_n)[1]
    return PushSpec(0.6 * high, 90.0, 0.1, 1.0)


def stage_calls(profile, model: Path, messages: list) -> dict[str, tuple[list, object]]:
    """Per stage, the calls over the recorded inputs and the reset before a pass."""
    chain = chain_for(profile, model)
    rec = record_stages(chain, messages)
    estimator, extractor, monitor = chain.pipeline.estimator, chain.extractor, chain.monitor
    return {'estimator': ([partial(estimator.update, s) for s in rec['samples']], estimator.reset),
            'features': ([partial(extractor.update, m) for m in rec['measurements']], extractor.reset),
            'predictor': ([partial(monitor.step, t, x, mode, tilt) for t, (x, mode), tilt
                           in zip(rec['times'], rec['features'], rec['tilts'])], monitor.new_run)}


def cpu_per_call_us(calls: list, reset) -> float:
    reset()
    c0 = time.thread_time_ns()
    for call in calls:
        call()
    return (time.thread_time_ns() - c0) / len(calls) / 1e3


def policy_cost(profile, calls: int) -> dict | None:
    controller = profile.controller_profile()
    if controller is None:
        return None
    config = load_policy_config(controller.policy_path)
    network = load_network(config.policy_path)
    rng = np.random.default_rng(0)
    observations = rng.normal(0.0, 0.5, size=(calls, network.input_size)).astype(np.float32)
    network.reset()
    per_call = np.empty(calls)
    clock = time.perf_counter_ns
    for i, obs in enumerate(observations):
        t0 = clock()
        network(obs)
        per_call[i] = clock() - t0
    return {'controller': controller.name, 'network': Path(config.policy_path).name,
            'describe': network.describe(), 'call_us_median': round(float(np.median(per_call)) / 1e3, 1),
            'call_us_p90': round(float(np.percentile(per_call, 90)) / 1e3, 1), 'calls': calls}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--reference', default='default_model.json', help='the reference model')
    parser.add_argument('--duration', type=float, default=4.0, help='simulated seconds per robot')
    parser.add_argument('--repeats', type=int, default=5, help='round-robin rounds')
    parser.add_argument('--policy-calls', type=int, default=2000)
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)

    models = shipped_models()
    if args.reference not in models:
        parser.error(f'--reference {args.reference}: not a shipped model ({", ".join(models)})')
    profiles = {robot: load_profile(robot) for robot in sorted(set(models.values()))}
    messages = {robot: messages_of(p, args.duration, push_for(p), seed=0) for robot, p in profiles.items()}
    calls = {name: stage_calls(profiles[robot], MODELS / name, messages[robot])
             for name, robot in models.items()}
    rounds: dict[str, list[dict[str, float]]] = {name: [] for name in models}
    for _ in range(args.repeats):
        for name in models:
            rounds[name].append({stage: cpu_per_call_us(*calls[name][stage]) for stage in calls[name]})

    def least(name: str, stage: str) -> float:
        return min(r[stage] for r in rounds[name])
    rows = {}
    for name, robot in models.items():
        fp = [r['features'] + r['predictor'] for r in rounds[name]]
        rows[name] = {'robot': robot, 'samples': len(calls[name]['predictor'][0]),
                      'features_us': round(least(name, 'features'), 1),
                      'predictor_us': round(least(name, 'predictor'), 1),
                      'features_plus_predictor_us': round(min(fp), 1),
                      'estimator_us': round(least(name, 'estimator'), 1)}
    ref = rows[args.reference]
    for row in rows.values():
        row['ratio_to_reference'] = {
            'features_plus_predictor': round(row['features_plus_predictor_us'] / ref['features_plus_predictor_us'], 2),
            'estimator': round(row['estimator_us'] / ref['estimator_us'], 2)}
    result = {'command': 'benchmarks/bench_model_cost.py', 'reference': args.reference,
              'what': 'CPU per sample without ROS, one process, models timed round-robin; the least '
                      f'of {args.repeats} rounds',
              'models': rows,
              'policies': {robot: cost for robot, p in profiles.items()
                           if (cost := policy_cost(p, args.policy_calls)) is not None},
              'python': platform.python_version(), 'machine': platform.machine(),
              'cores': os.cpu_count(), 'load_average': [round(x, 2) for x in os.getloadavg()]}
    if args.out:
        text = write_json(args.out, result)
    else:
        import json
        text = json.dumps(result, indent=1)
    print(text)
    return result


if __name__ == '__main__':
    main()
