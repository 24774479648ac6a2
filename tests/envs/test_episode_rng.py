"""Per-env reset draws (`envs/episode_rng.py`): a batch with seeds [s1..sN] draws exactly the starts of N single envs
with those seeds, and one env draws what torch's global generator drew before.

physx_cpu runs one env per process, so the batch is checked at the sampler level: the start samplers of
`skills/starts.py`, the pick's object placement (an enclosed fridge shelf beside open tables) and the nav target,
over several procedural layouts at once on CPU tensors, against the same samplers run one env at a time. The real
one-env resets are pinned by tests/envs/test_episode_starts.py; on a GPU, bench/gpu_check.py compares whole
physx_cuda resets.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import torch

from aerobench.envs.checks import SafetyLimits
from aerobench.envs.episode_rng import EpisodeRNG
from aerobench.envs.geometry import drone_proxy_points_body, pack_boxes
from aerobench.envs.objects import get_object
from aerobench.envs.platforms import get_platform
from aerobench.envs.scenes import generate_layout
from aerobench.envs.skills.base import AeroSkillEnv
from aerobench.envs.skills.nav import NavEvaluator
from aerobench.envs.skills.pick import PickEvaluator
from aerobench.envs.skills.starts import EpisodeStarts

# (layout seed, episode seed, object) per env: the `home` scene has fridge shelves and tables, so some envs pick from
# inside the fridge (an extra draw) and their neighbours do not
ENVS = [(3, 101, "bowl"), (5, 7, "cracker_box"), (8, 20000063, "tuna_fish_can"), (13, 55, "sugar_box"),
        (21, 9, "master_chef_can")]
PICK_KINDS = ("fridge_shelf", "table", "counter")


class StubStarts(EpisodeStarts):
    """An `AeroSkillEnv`'s start-sampling state without a simulator: its layouts, packed supports and boxes, objects,
    and per-env generators; placing an object records where it went."""

    def __init__(self, envs: list[tuple[int, int, str]], scene: str = "home"):
        layout_seeds, episode_seeds, objects = zip(*envs)
        self.device = torch.device("cpu")
        self.num_envs = len(layout_seeds)
        self.layouts = [generate_layout(scene, np.random.default_rng(s)) for s in layout_seeds]
        AeroSkillEnv._pack_supports(self)
        self.static_boxes = pack_boxes([layout.boxes for layout in self.layouts], self.device)
        self.workspace_lo = torch.tensor([layout.workspace_lo for layout in self.layouts])
        self.workspace_hi = torch.tensor([layout.workspace_hi for layout in self.layouts])
        self.built = SimpleNamespace(fixtures={})
        self.platform = get_platform("arm")
        self.safety = SafetyLimits()
        self.proxy_points, self.proxy_radius = drone_proxy_points_body(self.platform)
        self.start_proxy_points = self.proxy_points
        self.setting = SimpleNamespace(pick_supports=PICK_KINDS)
        self.target_specs = [get_object(name) for name in objects]
        self.condition = None  # no evaluation condition (the target's mass as its class's)
        AeroSkillEnv._object_tensors(self)
        self.target, self.distractors = "target", ["distractor_0", "distractor_1"]
        self.placed: dict[str, dict[int, torch.Tensor]] = {}
        self.episode_rng = EpisodeRNG(self.num_envs, self.device)
        self.episode_rng.seed(range(self.num_envs), episode_seeds)

    def place_object(self, actor, env_idx, bottom, yaw):
        for k, i in enumerate(env_idx.tolist()):
            self.placed.setdefault(actor, {})[i] = torch.cat([bottom[k], yaw[k : k + 1]])


def reset_draws(env: StubStarts, env_idx: torch.Tensor) -> dict[str, torch.Tensor]:
    """A pick episode's draws as `AeroPickEnv._sample_episode` makes them, and a nav target, per env of `env_idx`."""
    pick = PickEvaluator(env)
    ok = pick.sample(env_idx)
    bottom = torch.stack([env.placed["target"][i][:3] for i in env_idx.tolist()])
    env.place_distractors(env_idx, bottom, PICK_KINDS)
    anchor = bottom + env.target_grasp_point[env_idx]
    airframe, yaw, free = env.sample_start(env_idx, anchor, pick.min_start_tcp_height(env_idx))
    nav = NavEvaluator(env)
    nav_ok = nav.sample_target(env_idx)
    rows = env_idx.tolist()
    draws = {
        "support": pick.support_index[env_idx], "enclosed": pick.enclosed[env_idx], "ok": ok,
        "airframe": airframe, "yaw": yaw, "free": free, "nav_target": nav.target[env_idx], "nav_ok": nav_ok,
        "nav_name": torch.tensor([hash(nav.target_names[i]) for i in rows]),
    }
    for actor in ("target", *env.distractors):
        draws[actor] = torch.stack([env.placed[actor][i] for i in rows])
    return draws


def test_a_batch_draws_the_starts_of_single_envs_with_the_same_seeds():
    batched = reset_draws(StubStarts(ENVS), torch.arange(len(ENVS)))
    assert batched["enclosed"].any() and not batched["enclosed"].all(), "the batch should mix enclosed and open picks"
    for i, env in enumerate(ENVS):
        single = reset_draws(StubStarts([env]), torch.arange(1))
        for name, value in single.items():
            assert torch.equal(batched[name][i : i + 1], value), f"env {i}: {name} differs from its one-env draw"


def test_a_partial_reset_in_any_order_draws_what_the_envs_draw_alone():
    whole = reset_draws(StubStarts(ENVS), torch.arange(len(ENVS)))
    rows = torch.tensor([3, 0, 4])
    partial = reset_draws(StubStarts(ENVS), rows)
    for name, value in partial.items():
        assert torch.equal(value, whole[name][rows]), name


def test_the_draws_differ_between_seeds():
    a = reset_draws(StubStarts([(3, 1, "bowl"), (3, 2, "bowl")]), torch.arange(2))
    assert not torch.equal(a["airframe"][0], a["airframe"][1])


@pytest.mark.parametrize("seed", [0, 7, 22000076])
def test_one_env_draws_what_the_seeded_global_generator_drew(seed):
    """Before per-env generators a seeded one-env reset drew from torch's global generator after
    `torch.manual_seed(seed)` (ManiSkill's reset); the per-env generator continues exactly that stream."""
    weights = torch.tensor([0.0, 1.0, 1.0, 0.0, 1.0])
    with torch.random.fork_rng():
        torch.manual_seed(seed)
        expected = [torch.multinomial(weights[None], 1)[:, 0], torch.rand(1, 2), torch.randn(1, 96, 3),
                    torch.rand(1, 96, 1), torch.rand(1), torch.randint(3, (1,)), torch.randint(5, (1,))]
    rng = EpisodeRNG(3, "cpu")
    rng.seed([1], [seed])
    rows = torch.tensor([1])
    got = [rng.multinomial(rows, [weights]), rng.rand(rows, 2), rng.randn(rows, 96, 3), rng.rand(rows, 96, 1),
           rng.rand(rows), rng.randint(3, rows), torch.randint(5, (1,), generator=rng[1])]
    for want, have in zip(expected, got):
        assert torch.equal(want, have)


def test_draws_for_no_env_are_empty_and_mismatched_seeds_are_refused():
    rng = EpisodeRNG(2, "cpu")
    assert rng.rand(torch.tensor([], dtype=torch.long), 2).shape == (0, 2)
    assert rng.multinomial([], []).shape == (0,)
    with pytest.raises(ValueError, match="2 seeds for 1 envs"):
        rng.seed([0], [1, 2])
