#!/usr/bin/env python3
"""The paper's Fig. 2: sideways pushes of growing magnitude from ONE fixed walk-cycle state.

Every push starts from the same simulator snapshot (same state, same controller state), is
applied sideways (90 deg: to the robot's left) at a fixed height above the CoM for 0.1 s, and
the time to fall (if any) is recorded. With ``--model`` the figure also shows when that
predictor (with ``--tau-his``) first says falling on each trajectory, like the paper's Fig. 12,
on the state it sees on a robot (``--state estimated``, the default: simulated sensors, the
drivers' messages, the state estimator) or on the simulator's true state (``--state true``).

    .venv/bin/python scripts/fig2_force_sweep.py --model models/default_model.json --tau-his 0.06 \
        --out docs/robots/asimo_like/fig2.json --png docs/robots/asimo_like/fig2_force_sweep.png
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from joblib import Parallel, delayed
from tqdm import tqdm

from fall_predictor.monitor.records import PushSpec

_PREFIX = {}


def _prefix(t_push: float, horizon_s: float, record_sensors: bool = False):
    from fall_predictor.sim.pybullet_world import PybulletWorld
    from fall_predictor.sim.trajectory import WalkPrefix

    key = (t_push, horizon_s, record_sensors)
    if key not in _PREFIX:
        _PREFIX[key] = WalkPrefix(PybulletWorld(), until_s=t_push, walk_duration_s=t_push + horizon_s + 5.0,
                                  snapshot_every_s=t_push, record_sensors=record_sensors)
    return _PREFIX[key]


def _estimated_measurements(result, seed: int) -> list:
    """The run as the monitor sees it on a robot: the default sensor model (noise seeded by
    ``seed``), the drivers' messages, the state estimator (samples without an estimate left out)."""
    from dataclasses import replace

    from fall_predictor.monitor.sensor_pipeline import SensorPipeline
    from fall_predictor.profiles.profile import DEFAULT_ROBOT, load_profile
    from fall_predictor.sim.drivers import driver_messages
    from fall_predictor.sim.sensors import SensorParams, apply_sensors

    profile = load_profile(DEFAULT_ROBOT)
    layout = profile.sensor_layout()
    pipeline = SensorPipeline(layout.description(profile.urdf_xml()), layout.imu_frame,
                              layout.force_sensors)
    estimates = []
    for stream, reading in driver_messages(apply_sensors(result.sensor_truths, SensorParams(), seed=seed)):
        estimates.extend(pipeline.add(stream, reading))
    estimates.extend(pipeline.flush())
    return [replace(e.measurement, t=e.stamp_ns / 1e9) for e in estimates if e.measurement is not None]


def one(force: float, angle: float, height: float, t_push: float, horizon_s: float, model: str | None,
        tau_his_s: float, state: str = 'estimated') -> dict:
    from fall_predictor.sim.trajectory import run_trajectory

    push = PushSpec(force, angle, height, t_push)
    sensors = bool(model) and state == 'estimated'
    result = run_trajectory(push, push.t_force_end + horizon_s, prefix=_prefix(t_push, horizon_s, sensors),
                            record_sensors=sensors)
    row = {'force_n': force, 'fallen': result.fallen,
           'time_to_fall_s': None if not result.fallen else result.t_fallen - t_push,
           't_reflex': result.t_reflex}
    if model:
        from fall_predictor.monitor.features import extract_features
        from fall_predictor.monitor.model_file import load_model
        from fall_predictor.monitor.predictor import predict_trajectory

        lists, metadata = load_model(model)
        measurements = (_estimated_measurements(result, seed=int(round(force * 10)))
                        if state == 'estimated' else result.measurements)
        X, mode = extract_features(measurements)
        t = np.array([m.t for m in measurements])
        prediction = predict_trajectory(lists, X, mode, t, tau_his_s,
                                        guard_com_height_m=metadata.feature_settings.guard_com_height_m)
        t_predict = prediction.first_falling_time(t_push)
        row['time_to_predict_s'] = None if t_predict is None else t_predict - t_push
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--max-force', type=float, default=500.0)
    parser.add_argument('--step', type=float, default=2.0)
    parser.add_argument('--angle', type=float, default=90.0, help='deg from the heading (90: to the left)')
    parser.add_argument('--height', type=float, default=0.1, help='m above the CoM')
    parser.add_argument('--t-push', type=float, default=2.5, help='onset [s]: the fixed walk-cycle state')
    parser.add_argument('--horizon', type=float, default=5.0, help='s after the push ends')
    parser.add_argument('--model', default=None)
    parser.add_argument('--tau-his', type=float, default=0.06)
    parser.add_argument('--state', choices=('estimated', 'true'), default='estimated',
                        help="the model's input: the state estimated from simulated sensors (what "
                             'the shipped model sees on a robot; default) or the true state')
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', default='docs/robots/asimo_like/fig2.json')
    parser.add_argument('--png', default='docs/robots/asimo_like/fig2_force_sweep.png')
    args = parser.parse_args()

    forces = np.arange(0.0, args.max_force + 1e-9, args.step)
    start = time.time()
    rows = Parallel(n_jobs=args.jobs)(
        delayed(one)(float(f), args.angle, args.height, args.t_push, args.horizon, args.model,
                     args.tau_his, args.state)
        for f in tqdm(forces, desc='forces'))
    fallen = np.array([r['fallen'] for r in rows])
    first_fall = float(forces[np.argmax(fallen)]) if fallen.any() else None
    # Monotonic would mean: once a force fells the robot, every larger force does too.
    survivals_above_first_fall = [r['force_n'] for r in rows if first_fall is not None
                                  and r['force_n'] > first_fall and not r['fallen']]
    summary = {
        'command': 'scripts/fig2_force_sweep.py ' + ' '.join(
            f'--{k.replace("_", "-")} {v}' for k, v in vars(args).items() if v is not None),
        'largest_force_without_any_fall_below_n': None if first_fall is None else first_fall - args.step,
        'smallest_force_that_fells_n': first_fall,
        'monotonic': not survivals_above_first_fall,
        'survived_forces_above_first_fall_n': survivals_above_first_fall,
        'fall_fraction': float(fallen.mean()),
        'wall_s': time.time() - start,
        'rows': rows,
    }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(summary, indent=1))

    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 3.4))
    fall_t = [r['time_to_fall_s'] or 0.0 for r in rows]
    ax.bar(forces, fall_t, width=args.step * 0.9, color='#c0504d', label='time to fall')
    if args.model:
        pred_t = [r.get('time_to_predict_s') or 0.0 for r in rows]
        ax.bar(forces, pred_t, width=args.step * 0.45, color='#1f3b73',
               label=f'time to predict (tau_his {args.tau_his} s, {args.state} state)')
    ax.set_xlabel('push force [N] (0.1 s, sideways)')
    ax.set_ylabel('time after push onset [s]')
    ax.set_title(f'Pushes from one walk state (t = {args.t_push} s): gaps = no fall; '
                 f'{"monotonic" if summary["monotonic"] else "not monotonic"} in force')
    ax.set_xlim(-args.step, args.max_force + args.step)
    ax.legend(loc='upper right', fontsize=8)
    fig.tight_layout()
    Path(args.png).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.png, dpi=110)
    print(json.dumps({k: v for k, v in summary.items() if k != 'rows'}, indent=1))


if __name__ == '__main__':
    main()
