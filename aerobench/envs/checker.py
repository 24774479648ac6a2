"""An env checker in the spirit of gymnasium's: every registered aerobench env id and setting through reset and
step, checking shapes, dtypes, the per-step signals, determinism under a seed and robustness to random actions.

    from aerobench.envs.checker import check_env, ENV_CONFIGS
    for env_id, kwargs in ENV_CONFIGS: check_env(env_id, **kwargs)
"""

from __future__ import annotations

import gymnasium as gym
import torch

from .tasks import SETTINGS

SKILL_ENV_IDS = {"pick": "AeroPick-v1", "place": "AeroPlace-v1", "nav": "AeroNav-v1", "open": "AeroOpen-v1", "close": "AeroClose-v1"}

# Signals every env reports at every step, `(N,)` tensors (annotation reads them).
COMMON_INFO_KEYS = (
    "success", "fail", "fail_cause", "is_success", "tilt", "altitude", "speed", "angular_speed",
    "nontarget_contact_force", "airframe_contact_force", "gripper_opening", "min_obstacle_clearance",
    "init_failed", "subtask_index", "fail_tilt", "fail_low", "fail_high", "fail_workspace",
)
SKILL_INFO_KEYS = {
    "pick": ("is_grasped", "is_grasp_held", "lift_height", "is_lifted", "object_height", "tcp_to_grasp_point",
             "is_object_supported", "grasp_force_left", "grasp_force_right", "object_displacement", "object_rotation"),
    "place": ("is_grasped", "is_object_supported", "goal_distance", "is_aligned", "is_support_contact", "is_released", "release_registered",
              "is_gripper_clear", "platform_stable_steps", "collision_impulse", "is_set_down"),
    "nav": ("nav_distance", "is_nav_reached", "nav_settle_steps"),
    "open": ("articulation_progress", "is_handle_pinched", "is_goal_reached", "is_released_handle",
             "is_arm_retracted", "is_platform_stable", "no_airframe_contact", "min_clearance", "phase"),
}
SKILL_INFO_KEYS["close"] = SKILL_INFO_KEYS["open"]


def env_configs() -> list[tuple[str, dict]]:
    """(env id, kwargs) for every skill of every setting and every chain."""
    configs = []
    for setting in SETTINGS.values():
        for skill in setting.skills:
            configs.append((SKILL_ENV_IDS[skill], {"setting": setting.name}))
        for chain in setting.chains:
            configs.append(("AeroSequential-v1", {"setting": setting.name, "chain": chain}))
    return configs


def _flatten(obs, prefix=""):
    if isinstance(obs, dict):
        out = {}
        for k, v in obs.items():
            out.update(_flatten(v, f"{prefix}{k}/"))
        return out
    return {prefix.rstrip("/"): obs}


def check_env(env_id: str, steps: int = 8, obs_mode: str = "state_dict", seed: int = 3, **kwargs) -> None:
    """Raise AssertionError with a message naming the env and the broken property."""
    import aerobench.envs  # noqa: F401

    name = f"{env_id} {kwargs}"
    env = gym.make(env_id, obs_mode=obs_mode, **kwargs)
    try:
        base = env.unwrapped
        n = base.num_envs
        obs1, info = env.reset(seed=seed)
        flat1 = _flatten(obs1)
        obs2, _ = env.reset(seed=seed)
        flat2 = _flatten(obs2)
        assert flat1.keys() == flat2.keys(), f"{name}: observation keys differ between resets"
        for key in flat1:
            assert torch.equal(flat1[key], flat2[key]), f"{name}: same seed gave different observation {key}"
        state = obs1["agent"]["state"]
        assert state.shape == (n, 19 + (6 if base.platform.arm else 0)), f"{name}: state shape {tuple(state.shape)}"
        assert state.dtype == torch.float32, f"{name}: state dtype {state.dtype}"
        assert isinstance(base.get_instruction(0), str) and base.get_instruction(0), f"{name}: empty instruction"
        skills = [getattr(ev, "skill", "") for ev in base.evaluators]
        keys = set(COMMON_INFO_KEYS).union(*[SKILL_INFO_KEYS[s] for s in skills])
        action_space = env.action_space
        for _ in range(steps):
            action = torch.as_tensor(action_space.sample(), dtype=torch.float32)
            obs, reward, terminated, truncated, info = env.step(action)
            missing = keys - set(info)
            assert not missing, f"{name}: info lacks {sorted(missing)}"
            for key in keys:
                value = info[key]
                assert torch.is_tensor(value) and value.shape == (n,), f"{name}: info[{key!r}] is not an (N,) tensor"
            assert torch.isfinite(obs["agent"]["state"]).all(), f"{name}: non-finite state after a random action"
            assert terminated.dtype == torch.bool and terminated.shape == (n,), f"{name}: terminated not (N,) bool"
    finally:
        env.close()


def start_key(env_id: str, kwargs: dict, obj: str | None, seed: int) -> str:
    """The name of one recorded start: env id, its kwargs, the object and the episode seed."""
    return " ".join([env_id, *(f"{k}={v}" for k, v in sorted(kwargs.items())), f"object={obj}", f"seed={seed}"])


def start_record(env, row: int = 0) -> dict:
    """What the last reset drew for env `row`, as plain JSON values: the target's and each distractor's pose, the
    drone's joints, each fixture's joints, each goal marker's pose, each evaluator's goal (place goal, nav target,
    handle, opening, rest height), the fixture it chose, the instruction and whether the start was feasible. A batch
    and one env reset with the same seed give the same record (docs/gpu.md, "Seeds and starts")."""
    base = env.unwrapped
    record: dict = {}
    if base.target is not None:
        record["target"] = base.target.pose.raw_pose[row].tolist()
    for k, actor in enumerate(base.distractors):
        record[f"distractor_{k}"] = actor.pose.raw_pose[row].tolist()
    record["drone_qpos"] = base.agent.robot.get_qpos()[row].tolist()
    for name, fixture in base.built.fixtures.items():
        record[f"fixture/{name}"] = fixture.get_qpos()[row].tolist()
    for k, (_, marker) in enumerate(base.goal_markers):
        record[f"marker_{k}"] = marker.pose.raw_pose[row].tolist()
    for evaluator in base.evaluators:
        for name, value in evaluator.privileged_obs().items():
            record[f"goal/{name}"] = value[row].reshape(-1).tolist()
        if hasattr(evaluator, "fixture_id"):
            record[f"fixture_id/{evaluator.skill}"] = int(evaluator.fixture_id[row])
    record["instruction"] = base.get_instruction(row)
    record["init_failed"] = bool(base.init_failed[row])
    return record


def start_differences(want: dict, got: dict, tolerance: float) -> list[str]:
    """Where two `start_record`s differ: a field missing on either side, a number apart by more than `tolerance`,
    or any other value unequal. Empty when they are the same start."""
    problems = [f"{name}: only in one record" for name in sorted(want.keys() ^ got.keys())]
    for name in want.keys() & got.keys():
        a, b = want[name], got[name]
        if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
            gap = max((abs(x - y) for x, y in zip(a, b)), default=0.0)
            if not gap <= tolerance:
                problems.append(f"{name}: apart by {gap:.3g} (want {a}, got {b})")
        elif a != b:
            problems.append(f"{name}: want {a!r}, got {b!r}")
    return sorted(problems)
