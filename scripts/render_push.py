"""Render a pushed trajectory of the simulated robot as a strip of frames (PyBullet's
TinyRenderer, headless), so a reader sees what the robot does.

    .venv/bin/python scripts/render_push.py --force 250 --angle 90 --out docs/figures/push_survived.png
    .venv/bin/python scripts/render_push.py --force 450 --angle 90 --out docs/figures/push_fallen.png
    .venv/bin/python scripts/render_push.py --robot g1 --force 40 --angle 0 --after 2.0 \
        --out docs/figures/g1_walk_push_40n_forward.png
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pybullet as pb  # noqa: E402

from fall_predictor.monitor.records import PushSpec  # noqa: E402
from fall_predictor.profiles import DEFAULT_ROBOT, load_profile  # noqa: E402
from fall_predictor.robot.controllers import (BalanceController, ControllerSwitch,  # noqa: E402
                                              controller_configs)
from fall_predictor.sim.simulator import Simulator  # noqa: E402


def frame(sim: Simulator, target: np.ndarray, yaw_deg: float, size: tuple[int, int]) -> np.ndarray:
    view = pb.computeViewMatrixFromYawPitchRoll(cameraTargetPosition=[float(target[0]), float(target[1]), 0.42],
                                                distance=2.6, yaw=yaw_deg, pitch=-12.0, roll=0.0,
                                                upAxisIndex=2, physicsClientId=sim.client)
    proj = pb.computeProjectionMatrixFOV(fov=45.0, aspect=size[0] / size[1], nearVal=0.05, farVal=10.0,
                                         physicsClientId=sim.client)
    _, _, rgba, _, _ = pb.getCameraImage(size[0], size[1], view, proj, renderer=pb.ER_TINY_RENDERER,
                                         physicsClientId=sim.client)
    return np.reshape(np.asarray(rgba, dtype=np.uint8), (size[1], size[0], 4))[:, :, :3]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--force', type=float, default=250.0, help='push force [N] for 0.1 s')
    parser.add_argument('--angle', type=float, default=90.0, help='push direction from the heading [deg]')
    parser.add_argument('--height', type=float, default=0.1, help='above the CoM [m]')
    parser.add_argument('--onset', type=float, default=2.5, help='push onset [s]')
    parser.add_argument('--after', type=float, default=1.6, help='seconds shown after the onset')
    parser.add_argument('--frames', type=int, default=8)
    parser.add_argument('--robot', default=DEFAULT_ROBOT, help='robot profile (name or path)')
    parser.add_argument('--out', type=Path, required=True)
    args = parser.parse_args()
    profile = load_profile(args.robot)

    push = PushSpec(args.force, args.angle, args.height, args.onset)
    times = list(np.linspace(args.onset - 0.1, args.onset + args.after, args.frames))
    images, labels = [], []
    with Simulator(profile=profile) as sim:
        gait, reflex, stabilizer = controller_configs(profile)
        switch = ControllerSwitch(BalanceController(gait, reflex, stabilizer=stabilizer, profile=profile))
        q0, torso0 = switch.balance.initial_posture()
        m = sim.reset(q0, torso0)
        sim.draw_ground()
        sim.schedule_push(push)
        # Camera looks along the push, from the side, so the motion is in the image plane.
        yaw = args.angle
        anchor = None
        while times:
            sim.set_joint_targets(switch.update(m))
            m = sim.step()
            if anchor is None and m.t >= args.onset - 0.1:
                anchor = m.com.copy()
            if m.t >= times[0] - 1e-9:
                images.append(frame(sim, anchor, yaw, (320, 400)))
                contact = ('both feet' if len(m.left_contacts) and len(m.right_contacts) else
                           'left foot' if len(m.left_contacts) else
                           'right foot' if len(m.right_contacts) else 'no foot')
                labels.append(f't = {m.t - args.onset:+.2f} s\nCoM {m.com[2]:.2f} m, {contact}'
                              + (', fallen' if m.com[2] < profile.fallen_com_height_m else ''))
                times.pop(0)
    fig, axes = plt.subplots(1, len(images), figsize=(2.0 * len(images), 3.0))
    for ax, image, label in zip(axes, images, labels):
        ax.imshow(image)
        ax.set_title(label, fontsize=7)
        ax.axis('off')
    impulse = args.force * push.duration_s
    fig.suptitle(f'{impulse:.0f} N s push, {args.angle:.0f}° from the heading, '
                 f'{args.height:.2f} m above the CoM (t = 0: onset)', fontsize=9)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(args.out, 'fallen' if m.fallen else 'standing', f'{math.degrees(m.heading):.1f} deg heading')


if __name__ == '__main__':
    main()
