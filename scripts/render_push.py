"""Render a pushed run of a simulated robot as a strip of frames (headless: PyBullet's
TinyRenderer, MuJoCo's offscreen renderer), so a reader sees what the robot does under its
controller: C_bal, or a team's learned policy walking at a commanded velocity.

    .venv/bin/python scripts/render_push.py --force 250 --angle 90 --out docs/figures/push_survived.png
    .venv/bin/python scripts/render_push.py --force 450 --angle 90 --out docs/figures/push_fallen.png
    .venv/bin/python scripts/render_push.py --robot g1 --force 40 --angle 0 --after 2.0 \
        --out docs/figures/g1_walk_push_40n_forward.png
    .venv/bin/python scripts/render_push.py --robot g1_12dof --command 0.5 0 0 --force 500 \
        --angle 90 --onset 3.0 --out docs/figures/g1_policy_push.png
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fall_predictor.monitor.records import PushSpec  # noqa: E402
from fall_predictor.profiles import DEFAULT_ROBOT, load_profile  # noqa: E402
from fall_predictor.robot.control import make_controller  # noqa: E402
from fall_predictor.sim.trajectory import run_trajectory  # noqa: E402
from fall_predictor.sim.world import make_world  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--force', type=float, default=250.0, help='push force [N] for 0.1 s')
    parser.add_argument('--angle', type=float, default=90.0, help='push direction from the heading [deg]')
    parser.add_argument('--height', type=float, default=0.1, help='above the CoM [m]')
    parser.add_argument('--onset', type=float, default=2.5, help='push onset [s]')
    parser.add_argument('--after', type=float, default=1.6, help='seconds shown after the onset')
    parser.add_argument('--before', type=float, default=0.1, help='seconds shown before the onset')
    parser.add_argument('--frames', type=int, default=8)
    parser.add_argument('--robot', default=DEFAULT_ROBOT, help='robot profile (name or path)')
    parser.add_argument('--controller', default=None, help='walking controller (default: the profile\'s)')
    parser.add_argument('--simulator', default=None, help='pybullet or mujoco (default: the profile\'s)')
    parser.add_argument('--command', type=float, nargs=3, default=None, metavar=('VX', 'VY', 'YAW_RATE'),
                        help='a learned policy\'s velocity command [m/s, m/s, rad/s]')
    parser.add_argument('--out', type=Path, required=True)
    args = parser.parse_args()
    profile = load_profile(args.robot)
    controller = make_controller(profile, args.controller, args.command,
                                 walk_duration_s=args.onset + args.after + 5.0)
    world = make_world(profile, args.simulator, None if controller.name == 'c_bal'
                       else controller.policy.physics_dt_s)
    if hasattr(world, 'draw_ground'):
        world.start(controller.initial_posture())
        world.draw_ground()

    push = PushSpec(args.force, args.angle, args.height, args.onset)
    times = list(np.linspace(args.onset - args.before, args.onset + args.after, args.frames))
    images, labels, heading = [], [], []
    height_m = 0.42 * profile.guard_com_height_m / 0.48      # the ASIMO-like robot's view, scaled

    def on_step(w, m) -> None:
        if not heading and m.t >= args.onset - 1e-9:
            heading.append(math.degrees(m.heading))
        if times and m.t >= times[0] - 1e-9:
            # The camera follows the CoM, at right angles to the push: its motion in the image plane.
            yaw = (heading[0] if heading else math.degrees(m.heading)) + args.angle
            images.append(w.render(320, 400, (m.com[0], m.com[1], height_m), yaw))
            contact = ('both feet' if len(m.left_contacts) and len(m.right_contacts) else
                       'left foot' if len(m.left_contacts) else
                       'right foot' if len(m.right_contacts) else 'no foot')
            labels.append(f't = {m.t - args.onset:+.2f} s\nCoM {m.com[2]:.2f} m, {contact}'
                          + (', fallen' if m.com[2] < profile.fallen_com_height_m else ''))
            times.pop(0)
    result = run_trajectory(push, args.onset + args.after + 0.01, stop_when_fallen=False,
                            simulator=world, controller=controller, on_step=on_step)
    world.close()
    fig, axes = plt.subplots(1, len(images), figsize=(2.0 * len(images), 3.0))
    for ax, image, label in zip(np.atleast_1d(axes), images, labels):
        ax.imshow(image)
        ax.set_title(label, fontsize=7)
        ax.axis('off')
    impulse = args.force * push.duration_s
    who = controller.name + ('' if args.command is None else f' at ({", ".join(f"{c:g}" for c in args.command)})')
    fig.suptitle(f'{profile.name}, {who}: {impulse:.0f} N s push, {args.angle:.0f}° from the heading, '
                 f'{args.height:.2f} m above the CoM (t = 0: onset)', fontsize=9)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(args.out, f'fallen at {result.t_fallen:.3f} s' if result.fallen else 'standing')


if __name__ == '__main__':
    main()
