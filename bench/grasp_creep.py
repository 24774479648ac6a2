"""How far a pinched object slides through the closed jaws in hover, per PhysX solver setting (docs/physics.md).

The gripper platform is placed with its fingers on the object's grasp width (the tests' teleported hold), climbs for
one second and hovers; the object's height relative to the tool centre point is read every control step, and the
slide over the last 8 s of hover is printed in mm per control step with the finger force. Physically the object
should not move: each finger presses well above what friction needs to carry its weight.

    python bench/grasp_creep.py [--objects potted_meat_can,bowl,tomato_soup_can] [--steps 200]
"""

from __future__ import annotations

import argparse
import logging
import os

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
logging.getLogger("mani_skill").setLevel(logging.ERROR)

import gymnasium as gym  # noqa: E402
import torch  # noqa: E402

import aerobench.envs  # noqa: E402,F401
from aerobench.envs.skills.place import put_object_in_gripper  # noqa: E402

# (label, scene-config overrides); ManiSkill's default scene: TGS, 15 position / 1 velocity iterations
SETTINGS = (
    ("PGS (aerobench default)", dict(enable_tgs=False)),
    ("TGS, 15 position iterations (ManiSkill default)", dict(enable_tgs=True)),
    ("TGS, 4 position iterations", dict(enable_tgs=True, solver_position_iterations=4)),
    ("TGS, 50 position iterations", dict(enable_tgs=True, solver_position_iterations=50)),
    ("TGS, 8 velocity iterations", dict(enable_tgs=True, solver_velocity_iterations=8)),
    ("TGS, friction on the last iterations only", dict(enable_tgs=True, enable_friction_every_iteration=False)),
)
CLIMB_STEPS = 20  # 1 s at 0.3 of the speed limit, then hover
SETTLE_STEPS = 40  # the slide is measured from here on


def slide(obj: str, scene: dict, steps: int, seed: int = 2) -> tuple[float, float, bool]:
    """(mm per control step the object moved down relative to the TCP, median finger force N, still grasped)."""
    env = gym.make("AeroPick-v1", obs_mode="state_dict", object=obj, sim_config=dict(scene_config=scene))
    env.reset(seed=seed)
    base = env.unwrapped
    yaw = torch.zeros(1)
    tcp = base.agent.tcp_pose.p[0].clone()
    base.set_drone(torch.tensor([0]), (tcp + torch.tensor([0.0, 0.0, 0.28]))[None], yaw, base.target_grasp_width[0] / 2)
    put_object_in_gripper(base, torch.tensor([0]), yaw)
    rel, force = [], []
    for k in range(steps):
        action = torch.zeros(base.platform.action_dim)
        action[2] = 0.3 if k < CLIMB_STEPS else 0.0
        action[-1] = -1.0  # closed
        _, _, _, _, info = env.step(action)
        rel.append(float(info["object_height"][0] - info["tcp_height"][0]))
        force.append(float(info["grasp_force_left"][0]))
    grasped = bool(info["is_grasped"][0])
    env.close()
    n = steps - 1 - SETTLE_STEPS
    return 1000 * (rel[SETTLE_STEPS] - rel[-1]) / n, float(torch.tensor(force[SETTLE_STEPS:]).median()), grasped


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", default="potted_meat_can,bowl,tomato_soup_can")
    parser.add_argument("--steps", type=int, default=200)
    args = parser.parse_args(argv)
    if args.steps <= SETTLE_STEPS + 1:
        parser.error(f"--steps must exceed {SETTLE_STEPS + 1}")
    print(f"{'solver setting':48s} {'object':18s} {'slide mm/step':>14s} {'finger N':>9s} {'grasped':>8s}")
    for label, scene in SETTINGS:
        for obj in args.objects.split(","):
            mm, force, grasped = slide(obj, scene, args.steps)
            print(f"{label:48s} {obj:18s} {mm:14.4f} {force:9.2f} {str(grasped):>8s}", flush=True)


if __name__ == "__main__":
    main()
