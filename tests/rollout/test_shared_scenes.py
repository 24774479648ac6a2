"""Episodes that share a scene (`--episodes-per-scene G`): an env that finishes an episode is reset alone into its
next one (the runner's partial reset), each episode's start from its own seed, its scene from its group's first seed.

On a CPU an env is one batch row, so these tests run the path with N = 1; what makes them hold at any batch size is
that a row's draws come from its own seeded streams (`envs/episode_rng.py`, tests/envs/test_episode_starts.py).
"""

import gymnasium as gym
import numpy as np
import pytest
import torch

from aerobench.envs.checker import SKILL_ENV_IDS
from aerobench.policies.lerobot_policies import LeRobotPolicy
from aerobench.policies.remote import RemotePolicy
from aerobench.rollout.episode import EpisodeList
from aerobench.rollout.runner import RolloutRunner, RolloutSpec, check_resets_alone, plan_episodes, scene_chunks

STEPS = 25  # a few control steps an episode: the starts and the bookkeeping are the point, not the flight


def _spec(**kwargs) -> RolloutSpec:
    base = dict(setting="TidyHouse", skills=("pick",), episodes=3, objects=("sugar_box",), seed=11,
                record_cameras=False, max_steps=STEPS)
    return RolloutSpec(**{**base, **kwargs})


class _Holding(EpisodeList):
    """An in-memory sink that already holds some episodes (a run resumed after they were written)."""

    def __init__(self, done: set[int]):
        super().__init__()
        self.done = done

    def done_indices(self) -> set[int]:
        return set(self.done)


def _run(spec: RolloutSpec, done: frozenset[int] = frozenset()) -> dict[int, object]:
    sink = _Holding(set(done))
    RolloutRunner(spec, sink).run()
    return {ep.record.episode_index: ep for ep in sink.episodes}


def test_scene_groups_are_per_skill_and_object_and_fixed_by_the_plan():
    spec = RolloutSpec(setting="TidyHouse", skills=("pick", "place"), episodes=10, objects=("sugar_box", "bowl"),
                       seed=2, episodes_per_scene=2)
    plans = plan_episodes(spec)
    for plan in plans:  # each scene: its (skill, object)'s 2 consecutive episodes, named by the first one's seed
        group = [p for p in plans if (p.skill, p.object) == (plan.skill, plan.object)]
        position = group.index(plan)
        assert plan.scene == group[position - position % 2].seed
    assert plans[0].scene_seed is None and plans[4].scene == plans[0].seed  # pick sugar_box: episodes 0 and 4
    chunks = scene_chunks(plans)
    assert [[p.index for p in c] for c in chunks] == [[0, 4], [1, 5], [2, 6], [3, 7], [8], [9]]
    # one episode a scene: every plan is its own, as before the option existed (the committed rows)
    assert all(p.scene_seed is None for p in plan_episodes(_spec(episodes=6)))
    assert "episodes_per_scene" not in _spec().as_dict() and _spec(episodes_per_scene=3).as_dict()["episodes_per_scene"] == 3


@pytest.mark.parametrize("kwargs, message", [
    (dict(episodes_per_scene=0), "--episodes-per-scene must be a positive integer"),
    (dict(skills=("deliver",), setting="PackageDelivery", objects=None, chained=True, episodes_per_scene=2),
     "use --episodes-per-scene 1 with --chain or --realtime"),
])
def test_bad_scene_sharing_is_one_line(kwargs, message):
    with pytest.raises(ValueError, match=message):
        _spec(**kwargs)


def test_a_policy_with_one_queue_for_the_batch_is_refused_where_envs_are_reset_alone():
    for policy in (LeRobotPolicy, RemotePolicy):  # LeRobot's action queue (and the served one) is per batch
        with pytest.raises(ValueError, match="use --episodes-per-scene 1 with --num-envs 4"):
            check_resets_alone(policy, "act", 4)
        check_resets_alone(policy, "act", 1)  # one env: its reset clears only its own queue
    check_resets_alone(object(), "bc", 4)  # aerobench's own policies reset per env (their frame histories)


def test_an_episode_in_a_shared_scene_starts_from_its_own_seed_and_a_resumed_run_repeats_it():
    shared = _run(_spec(episodes_per_scene=2))
    plans = plan_episodes(_spec(episodes_per_scene=2))
    assert [shared[i].extra["scene_seed"] for i in range(3)] == [plans[0].seed, plans[0].seed, plans[2].seed]
    alone = _run(_spec(episodes=1))
    # the first episode of a scene is the episode as it runs alone, step for step
    for key in ("state", "task_state", "action"):
        np.testing.assert_array_equal(shared[0].frames[key], alone[0].frames[key])
    # the second starts where one env put there by the first seed's scene and the second seed's start begins
    env = gym.make(SKILL_ENV_IDS["pick"], setting="TidyHouse", obs_mode="state_dict", reconfiguration_freq=0,
                   max_episode_steps=STEPS)
    try:
        env.reset(seed=plans[0].seed, options={"reconfigure": True, "objects": ["sugar_box"]})
        obs, _ = env.reset(seed=plans[1].seed, options={"env_idx": torch.tensor([0]), "reconfigure": False})
        np.testing.assert_allclose(shared[1].frames["state"][0], obs["agent"]["state"][0].numpy(), atol=1e-6)
        np.testing.assert_allclose(shared[1].frames["task_state"][0], env.unwrapped.task_state()[0].numpy(), atol=1e-6)
    finally:
        env.close()
    assert not np.allclose(shared[1].frames["state"][0], shared[0].frames["state"][0])  # another start
    # resumed after the first episode was written: the second is rebuilt in its scene and runs the same
    resumed = _run(_spec(episodes_per_scene=2), done=frozenset({0}))
    assert sorted(resumed) == [1, 2]
    for i in (1, 2):
        for key in ("state", "task_state", "action"):
            np.testing.assert_array_equal(resumed[i].frames[key], shared[i].frames[key])
        assert resumed[i].record.outcome == shared[i].record.outcome
