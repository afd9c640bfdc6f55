"""The G1 on its own topic: held-out simulated G1 runs under Unitree's policy, replayed as the
``lowstate`` a G1 publishes, against the same runs as ``joint_states`` + ``imu/data``.

For ``--runs`` runs drawn from the policy's push protocol (its force and command ranges, seed
``--seed``, not the training seeds) of ``g1_12dof`` in MuJoCo with the sensor model on:

* **replay** (``--out-replay``): each run through the onboard monitor with the shipped model twice,
  as the standard sensor topics and re-encoded as ``lowstate`` (500 Hz, 29 motor slots with the
  held waist and arms, tick, no stamp, pelvis IMU w-x-y-z, serialized and read back, received with
  0.4-0.7 ms of latency): the alarm sample of each, their difference, alarms on survived runs, and
  DEGRADED samples of each path;
* **held joints** (``--out-held``): the estimate from the 29-joint description with the held
  joints as reported against the 12-joint description's (what the monitor runs): CoM, momenta,
  CoP, contact mode (:mod:`fall_predictor.data.held_joints`).

Usage::

    python benchmarks/bench_lowstate_g1.py --runs 20 \
        --out-replay docs/monitor/lowstate_replay_g1.json \
        --out-held docs/estimation/g1_held_joints.json
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from fall_predictor.contract.unitree_hg import lowstate_cdr, lowstate_record
from fall_predictor.data.held_joints import held_joint_errors, summarise_held
from fall_predictor.data.onboard_replay import (lowstate_messages, onboard_chain, replay,
                                                standard_messages)
from fall_predictor.monitor.fall_monitor import STATUS_DEGRADED
from fall_predictor.monitor.lowstate import LowStateConverter
from fall_predictor.profiles.profile import load_profile
from fall_predictor.robot.control import make_controller
from fall_predictor.sim.lowstate_driver import RECEIVE_EPOCH_NS, BoardTiming, lowstate_records
from fall_predictor.sim.policy_runs import commanded_pushes, physics_dt_s
from fall_predictor.sim.sensors import SensorParams, SensorSuite
from fall_predictor.sim.trajectory import run_trajectory
from fall_predictor.sim.world import make_world

ROBOT = 'g1_12dof'
AFTER_PUSH_S = 2.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--runs', type=int, default=20)
    parser.add_argument('--seed', type=int, default=6060)
    parser.add_argument('--out-replay', type=Path)
    parser.add_argument('--out-held', type=Path)
    args = parser.parse_args()
    profile = load_profile(ROBOT)
    policy = profile.controller_profile()
    model = Path(__file__).resolve().parents[1] / 'models' / profile.model
    pushes = commanded_pushes(policy)
    rng = np.random.default_rng(args.seed)
    rows, held = [], []
    started = time.monotonic()
    for k in range(args.runs):
        command, push = pushes.sample(rng)
        world = make_world(profile, None, physics_dt_s(policy))
        run = run_trajectory(push, push.t_push + AFTER_PUSH_S, world=world,
                             controller=make_controller(profile, None, command, dt_s=world.dt_s),
                             sensors=SensorSuite(SensorParams(), args.seed + k, world.dt_s, profile))
        world.close()
        readings = run.sensor_readings
        messages, index = standard_messages(readings, profile.imu_frame, RECEIVE_EPOCH_NS)
        standard = replay(onboard_chain(profile, model), messages, index)
        records = [(t, lowstate_record(lowstate_cdr(r))) for t, r in lowstate_records(
            readings, profile.unitree_hg, 5, BoardTiming(seed=k))]
        converter = LowStateConverter(profile.unitree_hg, profile.imu_frame, profile.joint_names)
        messages, index = lowstate_messages(records, converter)
        lowstate = replay(onboard_chain(profile, model), messages, index)
        rows.append({'run': k, 'force_n': round(push.force_n, 1), 'angle_deg': round(push.angle_deg, 1),
                     't_push_s': push.t_push, 'fallen': run.fallen, 't_fallen_s': run.t_fallen,
                     'alarm_sample_standard': standard.alarm_index,
                     'alarm_sample_lowstate': lowstate.alarm_index,
                     'alarm_t_s': None if lowstate.alarm_index is None else readings[lowstate.alarm_index].t,
                     'degraded_standard': standard.statuses.count(STATUS_DEGRADED),
                     'degraded_lowstate': lowstate.statuses.count(STATUS_DEGRADED),
                     'samples': len(readings)})
        held.append(held_joint_errors(readings, push.t_push, seed=k))
        print(rows[-1], flush=True)
    falls = [r for r in rows if r['fallen']]
    both = [r for r in falls if r['alarm_sample_standard'] is not None and r['alarm_sample_lowstate'] is not None]
    diffs = [abs(r['alarm_sample_standard'] - r['alarm_sample_lowstate']) for r in both]
    survived = [r for r in rows if not r['fallen']]
    result = {
        'robot': ROBOT, 'model': profile.model, 'runs': len(rows), 'seed': args.seed,
        'fallen': len(falls), 'survived': len(survived),
        'falls_alarmed_standard': sum(r['alarm_sample_standard'] is not None for r in falls),
        'falls_alarmed_lowstate': sum(r['alarm_sample_lowstate'] is not None for r in falls),
        'alarm_sample_difference_max': max(diffs) if diffs else None,
        'alarms_on_survived_standard': sum(r['alarm_sample_standard'] is not None for r in survived),
        'alarms_on_survived_lowstate': sum(r['alarm_sample_lowstate'] is not None for r in survived),
        'lead_s_median': float(np.median([r['t_fallen_s'] - r['alarm_t_s'] for r in falls
                                          if r['alarm_t_s'] is not None])) if falls else None,
        'degraded_samples_standard': sum(r['degraded_standard'] for r in rows),
        'degraded_samples_lowstate': sum(r['degraded_lowstate'] for r in rows),
        'samples': sum(r['samples'] for r in rows),
        'seconds': round(time.monotonic() - started, 1), 'per_run': rows}
    summary = {'robot_measured': 'g1 (29 joints, held joints as reported)',
               'reference': 'g1_12dof (12 joints: what the monitor runs)', 'runs': len(held),
               **summarise_held(held)}
    print(json.dumps({k: v for k, v in result.items() if k != 'per_run'}, indent=1))
    print(json.dumps(summary, indent=1))
    if args.out_replay:
        args.out_replay.write_text(json.dumps(result, indent=1) + '\n')
    if args.out_held:
        args.out_held.write_text(json.dumps(summary, indent=1) + '\n')


if __name__ == '__main__':
    main()
