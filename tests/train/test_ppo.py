"""`aerobench train ppo` on CPU: the reward on hand-built info dicts; a few windows on Pick (state only) that are
deterministic, resume without lost or repeated windows, start from a BC checkpoint, and evaluate; one window that
starts from an image BC checkpoint and acts on the three cameras."""

import json
import math
from pathlib import Path

import pytest
import torch

from aerobench.envs.checks import FailureCause
from aerobench.export import DatasetSink, read_jsonl
from aerobench.policies.learned import load_weights
from aerobench.rollout.runner import RolloutRunner, RolloutSpec
from aerobench.threads import torch_threads
from aerobench.train.bc import BCConfig, train_bc
from aerobench.train.common import read_scalars
from aerobench.train.ppo import SUCCESS_WINDOW, PPOConfig, linear_decay, lr_factor, success_triggered, train_ppo
from aerobench.train.rewards import RewardWeights, closeness, potential, reward
from tests.cli_here import aerobench_here


def _info(n=2, **values) -> dict:
    base = {"success": 0.0, "fail": 0.0, "tilt": 0.0, "altitude": 1.5, "nontarget_contact_force": 0.0,
            "tcp_to_grasp_point": 0.5, "is_grasped": 0.0, "lift_height": 0.0}
    base.update(values)
    return {k: torch.as_tensor(v, dtype=torch.float32).expand(n).clone() if not torch.is_tensor(v) else v
            for k, v in base.items()}


def test_reward_terms_on_hand_built_infos():
    w, zero = RewardWeights(), torch.zeros(2, 5)
    far, near = _info(tcp_to_grasp_point=0.5), _info(tcp_to_grasp_point=0.3)
    r, phi, terms = reward("pick", near, potential("pick", far), zero)
    assert torch.allclose(terms["progress"], torch.full((2,), 0.2)) and torch.allclose(r, terms["progress"])
    assert torch.allclose(phi, torch.full((2,), -0.3))
    # moving away is punished just as much
    r_back, _, _ = reward("pick", far, potential("pick", near), zero)
    assert torch.allclose(r_back, -r)
    # grasped and lifted by the full threshold: +1 + 2 on the potential
    lifted = _info(tcp_to_grasp_point=0.0, is_grasped=1.0, lift_height=0.5)
    assert torch.allclose(potential("pick", lifted), torch.full((2,), 3.0))
    # a lift without a grasp (the object knocked upwards) earns nothing
    assert torch.allclose(potential("pick", _info(tcp_to_grasp_point=0.0, lift_height=0.5)), torch.zeros(2))
    same = potential("pick", near)
    _, _, t = reward("pick", _info(tcp_to_grasp_point=0.3, success=torch.tensor([1.0, 0.0])), same, zero)
    assert t["success"].tolist() == [w.success, 0.0]
    _, _, t = reward("pick", _info(tcp_to_grasp_point=0.3, fail=torch.tensor([0.0, 1.0])), same, zero)
    assert t["fail"].tolist() == [0.0, -w.fail]
    _, _, t = reward("pick", _info(tcp_to_grasp_point=0.3, tilt=torch.tensor([w.tilt_soft_rad - 0.1, w.tilt_soft_rad + 0.1])), same, zero)
    assert t["tilt"][0] == 0.0 and math.isclose(float(t["tilt"][1]), -0.1 * w.tilt, rel_tol=1e-4)
    _, _, t = reward("pick", _info(tcp_to_grasp_point=0.3, altitude=torch.tensor([w.altitude_floor_m + 0.2, w.altitude_floor_m - 0.1])), same, zero)
    assert t["altitude"][0] == 0.0 and math.isclose(float(t["altitude"][1]), -0.1 * w.altitude, rel_tol=1e-4)
    _, _, t = reward("pick", _info(tcp_to_grasp_point=0.3, nontarget_contact_force=torch.tensor([0.5, 50.0])), same, zero)
    assert t["contact"].tolist() == pytest.approx([-0.5 * w.contact, -w.contact])  # capped at the collision force
    _, _, t = reward("pick", near, same, torch.tensor([[0.0] * 5, [1.0] * 5]))
    assert t["action"].tolist() == pytest.approx([0.0, -5 * w.action])
    nav = {"nav_distance": torch.tensor([2.0])}
    assert potential("nav", nav).tolist() == [-2.0]
    close = {"tcp_to_handle": torch.tensor([0.0]), "is_handle_pinched": torch.tensor([1.0]),
             "articulation_progress": torch.tensor([0.25])}
    assert potential("close", close).tolist() == [2.5] and potential("open", close).tolist() == [1.5]
    with pytest.raises(ValueError, match="valid: pick, place, nav, open, close"):
        potential("fly", near)
    with pytest.raises(KeyError, match="goal_distance"):
        potential("place", near)


def test_dense_reward_pays_closeness_every_step_and_a_success_worth_staying():
    w, zero = RewardWeights(), torch.zeros(2, 5)
    d = torch.tensor([0.0, 0.05, 0.3, 1.0])
    c = closeness(d)
    assert c[0] == 1.0 and bool((c[1:] < c[:-1]).all()) and bool((c > 0).all())  # 1 at the goal, falling with d
    far, near = _info(tcp_to_grasp_point=0.5), _info(tcp_to_grasp_point=0.05)
    r_far, phi, t_far = reward("pick", far, potential("pick", far), zero, kind="dense")
    r_near, _, _ = reward("pick", near, potential("pick", far), zero, kind="dense")
    assert torch.allclose(phi, torch.full((2,), -0.5))  # the potential (and its diagnostics) stay the same
    assert bool((r_near > r_far).all()) and bool((r_far > 0).all())  # paid for being close, whatever came before
    assert torch.allclose(t_far["progress"], closeness(torch.tensor(0.5)) / 4 * torch.ones(2))
    done = _info(tcp_to_grasp_point=0.0, is_grasped=1.0, lift_height=0.5, success=1.0)
    _, _, t = reward("pick", done, potential("pick", done), zero, kind="dense", gamma=0.97)
    assert torch.allclose(t["progress"], torch.ones(2) * w.progress)  # the goal's value is the step's maximum
    assert torch.allclose(t["success"], torch.full((2,), w.progress / 0.03))
    with pytest.raises(ValueError, match="valid: potential, dense"):
        reward("pick", far, phi, zero, kind="shaped")
    with pytest.raises(ValueError, match="needs --gamma below 1"):
        PPOConfig(setting="TidyHouse", skill="pick", out="x", reward="dense", gamma=1.0)


def _config(out: Path, total: int, **kw) -> PPOConfig:
    return PPOConfig(setting="TidyHouse", skill="pick", objects=("master_chef_can",), out=str(out), total_steps=total,
                     seed=kw.pop("seed", 0), max_episode_steps=24, update_epochs=2, hidden=(32, 32), save_every=1,
                     progress=False, **kw)


def _state(run: Path) -> dict:
    return torch.load(run / "checkpoint" / "train_state.pt", weights_only=False)


def test_ppo_is_deterministic_and_resumes(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    train_ppo(_config(a, 64))
    train_ppo(_config(b, 64))
    wa, wb = load_weights(a / "checkpoint"), load_weights(b / "checkpoint")
    assert set(wa) >= {"log_std", "critic.mlp.0.weight", "actor.mlp.0.weight"}
    assert all(torch.equal(wa[k], wb[k]) for k in wa), "same seed must give the same weights"
    assert read_scalars(a, "losses/value_loss") == read_scalars(b, "losses/value_loss")
    first = read_jsonl(a / "train_episodes.jsonl")
    assert first == read_jsonl(b / "train_episodes.jsonl")
    assert len(first) >= 2 and all(r["length"] <= 24 for r in first)  # 24-step episodes end inside a 64-step window
    assert set(first[0]) == {"global_step", "episode", "success", "return", "length", "outcome", "peak_potential"}
    labels = {"success", "truncated"} | {c.label for c in FailureCause if c}
    assert all(r["outcome"] in labels and (r["outcome"] == "success") == r["success"] for r in first)
    assert all(r["outcome"] == "truncated" for r in first if r["length"] == 24)  # the time limit, not a failure
    assert all(r["outcome"] not in ("success", "truncated") for r in first if r["length"] < 24)
    assert all(-3.0 < r["peak_potential"] < 4.0 for r in first)  # pick: -distance + grasped + 2 x lift

    # an interrupted run logged a line after its checkpoint: the resumed run redoes that window instead of keeping it
    with open(b / "train_episodes.jsonl", "a") as f:
        f.write(json.dumps({"global_step": 70, "episode": 99, "success": True, "return": 0.0, "length": 1}) + "\n")
    saved = json.loads((b / "checkpoint" / "config.json").read_text())
    # saved before these existed: potential reward, constant learning rate
    for name in ("reward", "lr_decay_steps", "lr_decay_start", "lr_decay_at_success", "lr_decay_length"):
        del saved["train"][name]
    (b / "checkpoint" / "config.json").write_text(json.dumps(saved))
    b = b.rename(tmp_path / "b_moved")  # a run folder resumes wherever it was moved to
    train_ppo(_config(b, 128))
    state = _state(b)
    assert (state["global_step"], state["iteration"]) == (128, 2)
    episodes = read_jsonl(b / "train_episodes.jsonl")
    assert episodes[: len(first)] == first
    assert [r["episode"] for r in episodes] == list(range(1, len(episodes) + 1)) and state["episodes"] == len(episodes)
    assert all(64 < r["global_step"] <= 128 for r in episodes[len(first):]) and len(episodes) > len(first)
    assert [s for s, _ in read_scalars(b, "losses/policy_loss")] == [64, 128]
    assert [s for s, _ in read_scalars(b, "charts/SPS")] == [64, 128]
    wb2 = load_weights(b / "checkpoint")
    assert any(not torch.equal(wb[k], wb2[k]) for k in wb), "the resumed window must have trained"

    c = tmp_path / "c"
    train_ppo(_config(c, 64, seed=1))
    wc = load_weights(c / "checkpoint")
    assert any(not torch.equal(wa[k], wc[k]) for k in wa), "another seed must give other weights"

    # the dense reward: the same starts (same seed), every step paid for closeness, recorded with the run
    d = tmp_path / "d"
    train_ppo(_config(d, 64, reward="dense"))
    dense = read_jsonl(d / "train_episodes.jsonl")
    assert [r["length"] for r in dense[:1]] == [r["length"] for r in first[:1]]  # same policy until the first update
    assert all(r["return"] != f["return"] for r, f in zip(dense[:1], first[:1]))
    assert json.loads((d / "checkpoint" / "config.json").read_text())["train"]["reward"] == "dense"
    with pytest.raises(ValueError, match="reward differ"):
        train_ppo(_config(d, 128))  # resumed with the other reward: refused


def test_ppo_learning_rate_decays_with_the_step_count_across_a_resume(tmp_path):
    run = tmp_path / "lr"
    train_ppo(_config(run, 64, lr_decay_steps=128))
    assert read_scalars(run, "charts/learning_rate") == [(64, pytest.approx(3e-4))]  # the first window: full rate
    train_ppo(_config(run, 192, lr_decay_steps=128))  # resumed with a larger budget: the schedule does not move
    assert read_scalars(run, "charts/learning_rate") == [(64, pytest.approx(3e-4)), (128, pytest.approx(1.5e-4)),
                                                         (192, 0.0)]
    before = load_weights(run / "checkpoint")
    train_ppo(_config(run, 256, lr_decay_steps=128))  # past the schedule's end the policy no longer changes
    after = load_weights(run / "checkpoint")
    assert all(torch.equal(before[k], after[k]) for k in before)
    assert _state(run)["global_step"] == 256
    with pytest.raises(ValueError, match="lr_decay_steps differ"):
        train_ppo(_config(run, 320))  # resumed with a constant rate: refused
    with pytest.raises(ValueError, match="lr_decay_start differ"):
        train_ppo(_config(run, 320, lr_decay_steps=128, lr_decay_start=64))  # or with another schedule
    with pytest.raises(ValueError, match="--lr-decay-start must not be negative"):
        _config(run, 64, lr_decay_steps=-1)
    with pytest.raises(ValueError, match=r"--lr-decay-start \(128\) must be below --lr-decay-steps \(128\)"):
        _config(run, 64, lr_decay_steps=128, lr_decay_start=128)


def test_ppo_learning_rate_decays_once_training_succeeds_and_the_trigger_survives_a_resume(tmp_path):
    run = tmp_path / "trigger"
    train_ppo(_config(run, 64, lr_decay_at_success=0.03, lr_decay_length=128))
    assert _state(run)["lr_decay_from"] is None  # 24-step episodes from scratch never succeed: the rate holds
    # the success window is rebuilt from the run's episode log on a resume: let its last 100 hold 3 successes
    rows = [{"global_step": 64, "episode": k + 1, "success": k >= SUCCESS_WINDOW - 3, "return": 0.0, "length": 1}
            for k in range(SUCCESS_WINDOW)]
    (run / "train_episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    train_ppo(_config(run, 256, lr_decay_at_success=0.03, lr_decay_length=128))
    # the next window's failures keep 3 of the last 100 as successes: the decay starts at 128 and ends at 256
    assert read_scalars(run, "charts/lr_decay_from") == [(128, 128)]
    assert read_scalars(run, "charts/learning_rate") == [(64, pytest.approx(3e-4)), (128, pytest.approx(3e-4)),
                                                         (192, pytest.approx(3e-4)), (256, pytest.approx(1.5e-4))]
    assert _state(run)["lr_decay_from"] == 128
    train_ppo(_config(run, 320, lr_decay_at_success=0.03, lr_decay_length=128))  # resumed: the start is kept
    assert read_scalars(run, "charts/learning_rate")[-1] == (320, 0.0)
    with pytest.raises(ValueError, match="lr_decay_at_success differ"):
        train_ppo(_config(run, 384, lr_decay_at_success=0.05, lr_decay_length=128))
    with pytest.raises(ValueError, match="--lr-decay-at-success and --lr-decay-length go together"):
        _config(run, 64, lr_decay_at_success=0.03)
    with pytest.raises(ValueError, match="drop --lr-decay-steps and --lr-decay-start"):
        _config(run, 64, lr_decay_at_success=0.03, lr_decay_length=128, lr_decay_steps=256)
    with pytest.raises(ValueError, match=r"--lr-decay-at-success must lie in \[0, 1\]"):
        _config(run, 64, lr_decay_at_success=3, lr_decay_length=128)


def test_the_success_trigger_needs_a_full_window_and_the_factor_follows_its_start():
    config = _config(Path("unused"), 64, lr_decay_at_success=0.03, lr_decay_length=100)
    assert not success_triggered(config, [True] * 3)  # three lucky first episodes: not yet a full window
    assert not success_triggered(config, [False] * 98 + [True] * 2)
    assert success_triggered(config, [True] * 3 + [False] * 97)
    assert not success_triggered(_config(Path("unused"), 64), [True] * 100)  # no trigger asked for
    assert [lr_factor(config, s, None) for s in (0, 10**9)] == [1.0, 1.0]  # not triggered: constant
    assert [lr_factor(config, s, 500) for s in (400, 500, 550, 600, 700)] == pytest.approx([1, 1, 0.5, 0, 0])
    fixed = _config(Path("unused"), 64, lr_decay_steps=100, lr_decay_start=60)
    assert [lr_factor(fixed, s, 10) for s in (0, 70, 100)] == pytest.approx([1, 0.75, 0])  # the step count alone


def test_linear_decay_holds_until_its_start_then_falls_to_zero():
    assert [linear_decay(s, 0) for s in (0, 10**9)] == [1.0, 1.0]  # no schedule: constant
    assert [linear_decay(s, 100) for s in (0, 25, 100, 150)] == [1.0, 0.75, 0.0, 0.0]
    assert [linear_decay(s, 100, start=60) for s in (0, 60, 70, 90, 100, 150)] == pytest.approx([1, 1, 0.75, 0.25, 0, 0])


def _bc_from_one_short_expert_episode(root: Path, max_steps: int, cameras: bool, **bc) -> Path:
    """A small BC actor from one truncated expert Pick episode (so it trains on outcome T: plumbing, not skill)."""
    spec = RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=1, objects=("master_chef_can",),
                       policy="expert", record_cameras=cameras, max_steps=max_steps)
    sink = DatasetSink(root / "ds", {**spec.as_dict(), "keep": "all"})
    with torch_threads(1):
        RolloutRunner(spec, sink).run()
    sink.close()
    return train_bc(BCConfig(dataset=str(root / "ds"), out=str(root / "bc"), outcomes=("T",), progress=False, **bc))


@pytest.fixture(scope="module")
def bc_checkpoint(tmp_path_factory) -> Path:
    return _bc_from_one_short_expert_episode(tmp_path_factory.mktemp("ppo_bc"), 20, False, steps=20, hidden=(32, 32),
                                             batch_size=16)


def test_ppo_from_bc_keeps_the_actor_during_critic_warmup_and_evaluates(bc_checkpoint, tmp_path):
    run = tmp_path / "ppo"
    ckpt = train_ppo(_config(run, 64, init_bc=str(bc_checkpoint), critic_warmup_steps=64, bc_coef=0.1))
    bc, ppo = load_weights(bc_checkpoint), load_weights(ckpt)
    actor_keys = [k for k in bc if k.startswith("actor.")]
    assert actor_keys and all(torch.equal(bc[k], ppo[k]) for k in actor_keys), "the actor starts as BC's"
    assert json.loads((ckpt / "normalization.json").read_text()) == json.loads(
        (bc_checkpoint / "normalization.json").read_text())
    critic_lr = read_scalars(run, "losses/value_loss")
    assert len(critic_lr) == 1 and math.isfinite(critic_lr[0][1])
    config = json.loads((ckpt / "config.json").read_text())
    assert config["algorithm"] == "ppo" and config["train"]["init_bc"] == str(bc_checkpoint)  # as given: no machine path

    out = tmp_path / "eval"
    proc = aerobench_here("eval", "--policy", "ppo", "--checkpoint", str(run), "--setting", "TidyHouse", "--skills",
                          "pick", "--objects", "master_chef_can", "--episodes-per-object", "2", "--max-steps", "8",
                          "--out", str(out))
    assert proc.returncode == 0, proc.stderr[-3000:]
    results = json.loads((out / "results.json").read_text())
    (cell,) = results["cells"]
    assert results["policy"] == "ppo" and cell["n"] == 2 and sum(cell["outcomes"].values()) == 2
    assert all(r["steps"] <= 8 and r["policy"] == "ppo" for r in read_jsonl(out / "records.jsonl"))


def test_ppo_from_an_image_bc_checkpoint_acts_on_the_three_cameras(tmp_path):
    """An image BC actor (three RGB-D cameras) starts PPO: the env renders the cameras, the actor keeps BC's encoder
    during critic warm-up, and the PPO checkpoint is an image policy too."""
    bc = _bc_from_one_short_expert_episode(tmp_path, 12, True, steps=4, batch_size=8, images=True, image_size=32,
                                           hidden=(32,))
    run = tmp_path / "ppo"
    ckpt = train_ppo(_config(run, 64, init_bc=str(bc), critic_warmup_steps=64))
    config = json.loads((ckpt / "config.json").read_text())
    assert config["model"]["cameras"] == ["drone_front", "drone_hand", "drone_own"]
    assert config["model"]["image_size"] == 32
    bc_w, ppo_w = load_weights(bc), load_weights(ckpt)
    encoder = [k for k in bc_w if k.startswith("actor.encoder.")]
    assert encoder and all(torch.equal(bc_w[k], ppo_w[k]) for k in bc_w if k.startswith("actor."))
    assert read_scalars(run, "charts/SPS"), "one window of 64 camera steps was collected"
    from aerobench.policies import policy_needs_images

    assert policy_needs_images("ppo", str(ckpt)) is True


@pytest.mark.gpu
def test_ppo_steps_many_envs_together_on_physx_cuda(tmp_path):
    """8 envs x 64 steps on physx_cuda: one window holds 512 transitions, and the run saves a checkpoint."""
    run = tmp_path / "ppo"
    ckpt = train_ppo(_config(run, 512, num_envs=8, sim_backend="physx_cuda", num_minibatches=4))
    assert _state(run)["global_step"] == 512
    assert json.loads((ckpt / "config.json").read_text())["train"]["num_envs"] == 8
    assert all(math.isfinite(v) for _, v in read_scalars(run, "losses/policy_loss"))


def test_ppo_steps_envs_in_worker_processes_on_physx_cpu(tmp_path):
    """--num-envs 2 on physx_cpu: two worker processes, 24-step episodes reset per env inside the 64-step windows,
    every episode started from a traceable seed."""
    run = tmp_path / "ppo"
    ckpt = train_ppo(_config(run, 256, num_envs=2, num_minibatches=4))
    state = _state(run)
    assert state["global_step"] == 256 and state["iteration"] == 2
    episodes = read_jsonl(run / "train_episodes.jsonl")
    assert len(episodes) >= 8 and all(r["length"] <= 24 for r in episodes)
    # 2 initial starts + one per finished episode (an infeasible start is re-drawn and counted too)
    assert state["episodes_started"] >= 2 + len(episodes)
    assert json.loads((ckpt / "config.json").read_text())["train"]["num_envs"] == 2
    assert all(math.isfinite(v) for _, v in read_scalars(run, "losses/policy_loss"))


@pytest.mark.xdist_group("ray")  # one local Ray runtime at a time (tests/rollout/test_ray.py)
@pytest.mark.parametrize("workers", ["processes", "ray"])
def test_rollout_workers_collect_the_windows_of_in_process_collectors(tmp_path, workers):
    """Worker i of 2 (a process, or a Ray actor) collects exactly the window an in-process collector of lane i
    collects with the same policy and noise seed, episodes reset inside it, from the lane's own starts."""
    from torch import nn

    from aerobench.envs.platforms import get_platform
    from aerobench.policies.learned import Normalizer, identity_stats, make_actor, make_critic, model_spec
    from aerobench.train.ppo_rollout import Collector, Fragment, SkillEnv
    from aerobench.train.rollout_workers import ProcessWorkers, RayWorkers

    config = _config(tmp_path / "run", 64, num_envs=2)
    pool = ProcessWorkers(config, "state_dict", 2, 0) if workers == "processes" else \
        RayWorkers(config, "state_dict", 2, 0, "local")
    try:
        platform = get_platform(pool.platform_name)
        inputs = config.input_spec(platform.arm is not None)
        dim, action_dim = pool.call("state_dim", inputs.as_dict())[0], platform.action_dim
        model = model_spec(dim, action_dim, config.hidden, inputs, gripper=config.gripper)
        torch.manual_seed(3)
        actor, critic = make_actor(model), make_critic(model)
        log_std, normalizer = nn.Parameter(torch.full((action_dim - 1,), -0.5)), Normalizer(identity_stats(dim, action_dim))
        policy = {"actor": actor.state_dict(), "critic": critic.state_dict(), "log_std": log_std.detach(),
                  "normalizer": normalizer.state_dict()}
        windows = pool.call("collect", model, policy, 40, config.gamma, 7)
    finally:
        pool.close()
        if workers == "ray":
            import ray

            ray.shutdown()
    for lane, window in enumerate(windows):
        env = SkillEnv(config, "state_dict", 1, lane, 2)
        with torch_threads(1):
            collector = Collector(env, *env.reset_all(), inputs, model, actor, critic, log_std, normalizer)
            torch.manual_seed(7 * 2 + lane)
            ref = collector.collect(40, config.gamma)
        env.close()
        for name in ("raw_state", "actions", "logprobs", "rewards", "dones", "values", "next_value", "next_done"):
            torch.testing.assert_close(getattr(window, name), getattr(ref, name), msg=f"lane {lane}: {name}")
        assert window.episodes == ref.episodes and len(ref.episodes) >= 1  # 24-step episodes end inside 40 steps
        assert window.starts_bound == ref.starts_bound == 2 * (1 + len(ref.episodes))  # one start per episode
    joined = Fragment.join(windows)
    assert joined.rewards.shape == (40, 2) and joined.next_value.shape == (2,)
    assert [e["row"] for e in joined.episodes if e["step"] == windows[1].episodes[0]["step"]][-1] == 1


@pytest.mark.xdist_group("ray")  # one local Ray runtime at a time (tests/rollout/test_ray.py)
def test_ppo_rollout_workers_on_ray(tmp_path):
    """--ray: the two envs are Ray actors of a local runtime, the learner runs here; same bookkeeping as processes."""
    import ray

    run = tmp_path / "ppo"
    try:
        train_ppo(_config(run, 128, num_envs=2, num_minibatches=4, ray="local"))
    finally:
        ray.shutdown()
    state = _state(run)
    assert state["global_step"] == 128 and state["iteration"] == 1
    episodes = read_jsonl(run / "train_episodes.jsonl")
    assert len(episodes) >= 4 and all(r["length"] <= 24 for r in episodes)
    assert state["episodes_started"] >= 2 + len(episodes)


def test_ppo_config_errors_are_one_line(tmp_path):
    with pytest.raises(ValueError, match="unknown skill 'fly'; PPO trains one of: pick, place, nav, open, close"):
        PPOConfig(setting="TidyHouse", skill="fly", out=str(tmp_path))
    with pytest.raises(ValueError, match="add --init-bc DIR"):
        PPOConfig(setting="TidyHouse", skill="pick", out=str(tmp_path), bc_coef=0.5)
    with pytest.raises(ValueError, match="no aerobench bc/ppo checkpoint at .*must hold config.json"):
        PPOConfig(setting="TidyHouse", skill="pick", out=str(tmp_path), init_bc=str(tmp_path / "none"))
    with pytest.raises(ValueError, match="unknown controller 'x'; valid controllers: payload-aware, nominal"):
        PPOConfig(setting="TidyHouse", skill="pick", out=str(tmp_path), controller="x")
    with pytest.raises(ValueError, match="--num-minibatches"):
        PPOConfig(setting="TidyHouse", skill="pick", out=str(tmp_path), num_minibatches=5)
    with pytest.raises(ValueError, match="--ray runs the --num-envs physx_cpu envs as Ray actors: give --num-envs 2"):
        PPOConfig(setting="TidyHouse", skill="pick", out=str(tmp_path), ray="local")
    proc = aerobench_here("train", "ppo", "--setting", "Nowhere", "--skill", "pick", "--out", str(tmp_path / "x"))
    assert proc.returncode == 2 and "TidyHouse" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_the_action_distribution_is_a_gaussian_with_a_bernoulli_gripper():
    from torch.distributions import Normal

    from aerobench.train.ppo import ActionDistribution

    out, log_std = torch.tensor([[0.5, -0.2, 0.0, 0.1, 2.0]]), torch.full((4,), -1.0)
    dist = ActionDistribution(out, log_std, binary=True)
    close = torch.tensor([[0.4, -0.1, 0.0, 0.0, 1.0]])
    gaussian = Normal(out[:, :4], log_std.exp()).log_prob(close[:, :4]).sum(-1)
    assert torch.allclose(dist.log_prob(close), gaussian + torch.log(torch.sigmoid(torch.tensor(2.0))))
    open_ = torch.cat([close[:, :4], torch.zeros(1, 1)], -1)
    assert torch.allclose(dist.log_prob(open_), gaussian + torch.log(torch.sigmoid(torch.tensor(-2.0))))
    torch.manual_seed(0)
    samples = torch.cat([dist.sample() for _ in range(200)])
    assert set(samples[:, -1].tolist()) == {0.0, 1.0} and samples[:, -1].mean() > 0.8  # p(close) = 0.88
    assert dist.entropy().shape == (1,)
    continuous = ActionDistribution(out, torch.full((5,), -1.0), binary=False)
    assert torch.allclose(continuous.log_prob(out), Normal(out, torch.full((5,), -1.0).exp()).log_prob(out).sum(-1))
