#!/usr/bin/env python3
"""The monitor on a robot's sensor streams: a generated dataset replayed over DDS into
``fall_monitor --estimator`` (the robot's shipped model, or ``--model``) the way a robot's
drivers publish it, for any robot profile (``--robot``; a robot without foot force/torque
sensors publishes no wrenches).

For each trajectory of a dataset made with ``generate --sensor-noise 1`` (made here if missing),
its sensor samples are published in real time with ROS-time stamps (now, ns since 1970), each
stream re-timed by :class:`~fall_predictor.sim.drivers.DriverTiming`:

* ``simulator``: every stream at 1 kHz with one stamp per step (the simulator's own timing);
* ``robot_1khz``: joint states at 1 kHz split into legs and upper body, in reverse order; IMU and
  foot wrenches 0.3 / 0.4 ms after the encoders;
* ``robot_500hz``: the same with joint states at 500 Hz.

Reported per timing: falls detected before fallen, false alarms, median lead, the largest lead
difference to the same recording through the onboard chain offline with the simulator's timing
(:class:`~fall_predictor.monitor.chain.OnboardChain`), and states per estimate (driving joint
message). Writes JSON (``--out``).

    python benchmarks/bench_robot_streams.py --trajectories 8 --seed 11 --out docs/monitor/robot_streams_asimo_like.json
    python benchmarks/bench_robot_streams.py --robot g1 --data data/g1_test400 --trajectories 6
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from statistics import median

import numpy as np

from fall_predictor.cli import main as cli_main
from fall_predictor.data.dataset import read_index
from fall_predictor.data.onboard_replay import first_alarm, onboard_chain
from fall_predictor.data.sensorbag import read_robot_description, read_sensor_messages
from fall_predictor.monitor.sensor_records import SensorSample
from fall_predictor.profiles.profile import DEFAULT_ROBOT, load_profile
from fall_predictor.sim.drivers import DriverTiming, driver_messages

from portable_paths import portable             # noqa: E402  (benchmarks/ is on the path)

MODELS = Path(__file__).resolve().parents[1] / 'models'


def timings(profile) -> dict[str, DriverTiming]:
    """The three timings of the module docstring for a robot profile's joints."""
    legs, upper = profile.legs_and_upper_body()
    return {'simulator': DriverTiming(),
            'robot_1khz': DriverTiming.robot(1000.0, (legs, upper)),
            'robot_500hz': DriverTiming.robot(500.0, (legs, upper))}


#: The default robot's legs and timings (other benchmarks replay with them).
LEGS = load_profile(DEFAULT_ROBOT).legs_and_upper_body()[0]
TIMINGS = timings(load_profile(DEFAULT_ROBOT))


def samples_of(bag: Path) -> list[SensorSample]:
    """A simulator-timed bag's sensor messages back as one sample per step."""
    rows: dict[int, dict] = {}
    for stream, r in read_sensor_messages(bag):
        rows.setdefault(r.stamp_ns, {})[stream] = r
    out = []
    for ns in sorted(rows):
        row = rows[ns]
        j, imu = row['joints'], row['imu']
        left, right = row.get('l'), row.get('r')          # None: no force/torque sensor
        out.append(SensorSample(t=ns / 1e9, joint_names=j.names, q=j.position, dq=j.velocity,
                                tau=j.effort, imu_quat_xyzw=imu.orientation_xyzw,
                                gyro_rad_s=imu.angular_velocity, accel_m_s2=imu.linear_acceleration,
                                left_wrench=None if left is None else left.wrench,
                                right_wrench=None if right is None else right.wrench,
                                imu_frame=imu.frame_id,
                                wrench_frames=('' if left is None else left.frame_id,
                                               '' if right is None else right.frame_id)))
    return out


def offline_alarm_s(profile, model: Path, urdf: str, samples: list[SensorSample]) -> float | None:
    """The first alarm [s] of the onboard chain offline, simulator-timed (the reference)."""
    chain = onboard_chain(profile, model, urdf, driving_joints=profile.legs_and_upper_body()[0])
    alarm = first_alarm(chain, driver_messages(samples))
    return None if alarm is None else alarm.stamp_s


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--trajectories', type=int, default=8)
    parser.add_argument('--seed', type=int, default=11)
    parser.add_argument('--data', type=Path, default=None, help='dataset (made if missing)')
    parser.add_argument('--robot', default=DEFAULT_ROBOT, help='robot profile')
    parser.add_argument('--model', type=Path, default=None,
                        help="model file (default: the robot profile's shipped model)")
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    profile = load_profile(args.robot)
    model = args.model or MODELS / profile.model
    legs = profile.legs_and_upper_body()[0]
    replay_timings = timings(profile)

    import rclpy

    from fall_predictor.ros.bringup import ros_environment, start_process, stop_nodes
    from fall_predictor.ros.sensor_replay import SensorReplayer

    data = args.data or Path(tempfile.mkdtemp(prefix='robot_streams_')) / 'data'
    if not (data / 'dataset.json').exists():
        assert cli_main(['generate', '--robot', args.robot, '--trajectories', str(args.trajectories),
                         '--seed', str(args.seed), '--out', str(data), '--sensor-noise', '1',
                         '--json']) == 0
    rows = read_index(data)[:args.trajectories]
    recordings = []
    for row in rows:
        bag = data / row.bag
        samples = samples_of(bag)
        urdf = read_robot_description(bag)
        recordings.append((row, samples, offline_alarm_s(profile, model, urdf, samples)))
    urdf = read_robot_description(data / rows[0].bag)

    domain = 150 + int(time.time()) % 50
    log_dir = Path(tempfile.mkdtemp(prefix='robot_streams_logs_'))
    monitor = start_process('fall_monitor', [
        sys.executable, '-m', 'fall_predictor.ros.fall_monitor', '--estimator', '--ros-args',
        '-p', f'model_path:={model}', '-p', f'robot:={args.robot}',
        '-p', f'driving_joints:={list(legs)}'.replace("'", '"'),
        '-p', 'start_type_description_service:=false'], ros_environment(domain), log_dir)
    results = {name: [] for name in replay_timings}
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain)
    try:
        replayer = SensorReplayer(context)
        streams = ('joints', 'imu') + tuple(profile.sensor_layout().force_sensors)
        if not replayer.spin_until(lambda: replayer.connected(streams), 60.0):
            raise RuntimeError(f'the monitor did not come up:\n{monitor.log_tail()}')
        replayer.publish_description(urdf)
        time.sleep(1.0)
        for name, timing in replay_timings.items():
            for row, samples, reference in recordings:
                replayer.reset_monitor()
                r = replayer.replay(samples, timing)
                results[name].append({'trajectory': row.trajectory_id, 'fell': row.fallen,
                                      't_fallen': row.t_fallen, 'alarm_s': r.first_alarm_s,
                                      'reference_alarm_s': reference, 'states': r.states,
                                      'driving_messages': r.joint_messages // (2 if timing.joint_groups else 1),
                                      'status_counts': r.status_counts,
                                      'publish_lag_max_s': round(r.publish_lag_s, 4)})
                print(name, results[name][-1], file=sys.stderr)
        replayer.destroy()
    finally:
        rclpy.try_shutdown(context=context)
        stop_nodes({'fall_monitor': monitor})

    summary = {}
    for name, runs in results.items():
        falls = [r for r in runs if r['fell']]
        detected = [r for r in falls if r['alarm_s'] is not None and r['alarm_s'] < r['t_fallen']]
        leads = [r['t_fallen'] - r['alarm_s'] for r in detected]
        deltas = [abs((r['t_fallen'] - r['alarm_s']) - (r['t_fallen'] - r['reference_alarm_s']))
                  for r in detected if r['reference_alarm_s'] is not None]
        summary[name] = {
            'falls': len(falls), 'falls_detected': len(detected),
            'false_alarms': sum(r['alarm_s'] is not None for r in runs if not r['fell']),
            'survived': len(runs) - len(falls),
            'lead_median_s': round(median(leads), 3) if leads else None,
            'lead_delta_vs_offline_simulator_max_s': round(max(deltas), 4) if deltas else None,
            'states_per_estimate': round(sum(r['states'] for r in runs)
                                         / max(1, sum(r['driving_messages'] for r in runs)), 4),
        }
    reference_leads = [r['t_fallen'] - r['reference_alarm_s'] for _, r in
                       ((0, x) for x in results['simulator']) if r['fell'] and r['reference_alarm_s']]
    report = {'dataset': str(data), 'trajectories': len(rows), 'seed': args.seed,
              'robot': args.robot, 'model': str(model.name),
              'timings': {k: v.to_dict() for k, v in replay_timings.items()},
              'offline_simulator_lead_median_s': round(float(np.median(reference_leads)), 3)
              if reference_leads else None,
              'summary': summary, 'runs': results}
    text = json.dumps(portable(report), indent=1, sort_keys=True)   # no machine path committed
    print(json.dumps(summary, indent=1, sort_keys=True))
    if args.out:
        args.out.write_text(text + '\n')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
