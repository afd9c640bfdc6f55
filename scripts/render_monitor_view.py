#!/usr/bin/env python3
"""A replayed fall as the monitor sees it (what ``monitor_markers`` shows in RViz / Foxglove).

Simulates a push that fells the robot, records its sensors, replays them as a robot's drivers
publish them through the onboard chain (the shipped model), and draws the monitor's view
(:func:`fall_predictor.monitor.view.monitor_view`: support polygon, CoP, CoM ground projection,
capture point, predicted fall direction, status) from above: before the push, at the trigger, and
0.2 s after it.

    python scripts/render_monitor_view.py --out docs/monitor/monitor_view_fall.png
"""
from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402

from fall_predictor.data.onboard_replay import onboard_chain  # noqa: E402
from fall_predictor.monitor.fall_monitor import EVENT_FALLING  # noqa: E402
from fall_predictor.monitor.records import PushSpec  # noqa: E402
from fall_predictor.monitor.view import monitor_view  # noqa: E402
from fall_predictor.profiles import asimo_like_urdf as rm  # noqa: E402
from fall_predictor.sim.drivers import DriverTiming, driver_messages  # noqa: E402
from fall_predictor.sim.sensors import SensorParams, apply_sensors  # noqa: E402
from fall_predictor.sim.trajectory import run_trajectory  # noqa: E402

MODEL = Path(__file__).resolve().parents[1] / 'models' / 'default_model.json'


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--force', type=float, default=420.0, help='push force [N] (0.1 s)')
    parser.add_argument('--angle', type=float, default=0.0, help='push direction [deg]')
    parser.add_argument('--out', type=Path, default=Path('docs/monitor/monitor_view_fall.png'))
    args = parser.parse_args()
    run = run_trajectory(PushSpec(args.force, args.angle, 0.1, 1.0), 3.0, record_sensors=True)
    samples = apply_sensors(run.sensor_truths, SensorParams(), seed=0)
    chain = onboard_chain(rm.PROFILE, MODEL, rm.URDF_PATH.read_text())
    outputs = [o for stream, r in driver_messages(samples, DriverTiming.robot(500.0))
               for o in chain.add(stream, r) if o.measurement is not None]
    trigger = next(o for o in outputs if o.event is not None and o.event.kind == EVENT_FALLING)
    t0 = DriverTiming.robot().clock_offset_ns
    t_trigger = (trigger.stamp_ns - t0) / 1e9
    picks = [('before the push', 0.9), ('the trigger', t_trigger), ('0.2 s later', t_trigger + 0.2)]
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.6))
    for ax, (title, t) in zip(axes, picks):
        o = min(outputs, key=lambda o: abs((o.stamp_ns - t0) / 1e9 - t))
        v = monitor_view(o.measurement, o.state, rm.TOTAL_MASS_KG)
        if v.support_polygon:
            xs, ys = zip(*[*v.support_polygon, v.support_polygon[0]])
            ax.plot(xs, ys, '-', color='tab:green', label='support polygon')
        if v.cop is not None:
            ax.plot(*v.cop, 'o', color='tab:red', label='CoP')
        ax.plot(*v.com_ground, 'o', color='tab:blue', label='CoM (ground)')
        ax.plot(*v.capture_point, 's', color='tab:orange', label='capture point')
        if v.fall_direction is not None:
            ax.annotate('', xy=(v.com_ground[0] + 0.3 * v.fall_direction[0],
                                v.com_ground[1] + 0.3 * v.fall_direction[1]), xytext=v.com_ground,
                        arrowprops=dict(color='tab:red', width=2))
        words = v.state.word + (' (latched)' if v.state.latched else '')
        ax.set_title(f'{title}: t = {(o.stamp_ns - t0) / 1e9:.3f} s\n{words}')
        cx, cy = v.com_ground
        ax.set_xlim(cx - 0.45, cx + 0.45)
        ax.set_ylim(cy - 0.45, cy + 0.45)
        ax.set_aspect('equal')
        ax.grid(alpha=0.3)
        ax.set_xlabel('x (odom) [m]')
    axes[0].set_ylabel('y (odom) [m]')
    axes[0].legend(loc='lower left', fontsize=8)
    fig.suptitle(f'A {args.force:.0f} N push at {args.angle:.0f} deg, replayed as a robot\'s drivers publish '
                 f'it (fallen at {run.t_fallen:.3f} s): what fall_predictor/markers shows')
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f'{args.out}: trigger at {t_trigger:.3f} s, fallen at {run.t_fallen:.3f} s')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
