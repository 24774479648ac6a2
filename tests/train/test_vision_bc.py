"""The `vision` input tier end to end on a tiny camera dataset: a camera BC trains for seconds, evaluates in its tier,
its blind control renders nothing, and a feature outside the tier is refused at training and at evaluation."""

import json
import math
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from aerobench import tiers
from aerobench.depth import decode_depth_mm
from aerobench.export import DatasetSink
from aerobench.policies.camera_input import random_shift, reduce_depth, reduce_rgb
from aerobench.policies.egocentric import ego_features, to_heading_frame, to_world_frame, yaw_of
from aerobench.policies.instruction import instruction_tokens
from aerobench.rollout.runner import RolloutRunner, RolloutSpec
from aerobench.threads import torch_threads
from aerobench.train.bc import BCConfig, train_bc
from aerobench.train.camera_frames import camera_frames
from tests.cli_here import aerobench_here

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))  # the release calibration bench

pytestmark = pytest.mark.xdist_group("vision_bc")  # the module's camera dataset is made once, on one worker


@pytest.fixture(scope="module")
def camera_dataset(tmp_path_factory) -> Path:
    """Two PrepareGroceries Place episodes with cameras, cut at 10 steps (truncations: plumbing, not skill)."""
    root = tmp_path_factory.mktemp("vision") / "ds"
    spec = RolloutSpec(setting="PrepareGroceries", skills=("place",), episodes=2, objects=("sugar_box", "bowl"),
                       record_cameras=True, max_steps=10, seed=7)
    sink = DatasetSink(root, {**spec.as_dict(), "keep": "all"})
    with torch_threads(1):
        RolloutRunner(spec, sink).run()
    sink.close()
    return root


def _vision(camera_dataset: Path, out: Path, **kw) -> Path:
    config = dict(dataset=str(camera_dataset), out=str(out), steps=3, batch_size=8, images=True, inputs="vision",
                  outcomes=("T",), image_size=32, hidden=(32,), log_every=1, progress=False)
    return train_bc(BCConfig(**{**config, **kw}))


def test_a_vision_policy_trains_for_seconds_and_evaluates_in_its_tier(camera_dataset, tmp_path):
    from aerobench.eval.evaluate import EvalConfig, evaluate

    ckpt = _vision(camera_dataset, tmp_path / "run")
    config = json.loads((ckpt / "config.json").read_text())
    assert config["inputs_tier"] == "vision"
    assert config["model"]["inputs"]["task_fields"] == [] and config["model"]["inputs"]["action_frame"] == "heading"
    with torch_threads(1):
        results = evaluate(EvalConfig(policy="bc", setting="PrepareGroceries", skills=("place",),
                                      objects=("sugar_box",), episodes_per_object=1, checkpoint=str(ckpt), max_steps=3,
                                      seed=11, inputs="vision"), tmp_path / "eval")
    assert results["inputs"] == "vision" and results["cells"][0]["n"] == 1


def test_a_feature_outside_the_tier_is_refused_at_training_and_at_evaluation(camera_dataset, tmp_path):
    with pytest.raises(ValueError, match="observation.environment_state, which the vision tier does not admit"):
        BCConfig(dataset="d", out="o", inputs="vision", images=True, task_fields=("goal_pos",))
    proc = aerobench_here("train", "bc", "--dataset", str(camera_dataset), "--out", str(tmp_path / "x"),
                          "--inputs", "vision", "--task-fields", "goal_pos,heading_error")
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1
    assert "the vision tier does not admit" in proc.stderr
    privileged = train_bc(BCConfig(dataset=str(camera_dataset), out=str(tmp_path / "priv"), steps=2, batch_size=8,
                                   outcomes=("T",), hidden=(16,), progress=False))
    assert json.loads((privileged / "config.json").read_text())["inputs_tier"] == "privileged"
    proc = aerobench_here("eval", "--policy", "bc", "--checkpoint", str(privileged), "--setting", "PrepareGroceries",
                          "--skills", "place", "--episodes-per-object", "1", "--inputs", "vision",
                          "--out", str(tmp_path / "e"))
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1
    assert "reads observation.environment_state, which the vision tier does not admit" in proc.stderr
    assert not (tmp_path / "e").exists()  # refused before any work


def test_the_blind_control_is_the_same_network_with_its_cameras_blanked(camera_dataset, tmp_path):
    from aerobench.policies import policy_needs_images
    from aerobench.policies.learned import load_actor

    seeing = _vision(camera_dataset, tmp_path / "seeing")
    blind = _vision(camera_dataset, tmp_path / "blind", blind=True)
    a, b = load_actor(seeing)[1], load_actor(blind)[1]
    assert {k: v.shape for k, v in a.state_dict().items()} == {k: v.shape for k, v in b.state_dict().items()}
    assert policy_needs_images("bc", str(seeing)) and not policy_needs_images("bc", str(blind))
    x = {"state": torch.zeros(2, a.mlp[0].in_features - 64 * 3 - 32), "instruction": instruction_tokens(["a", "b"])}
    cams = {c: torch.rand(2, 4, 32, 32) for c in a.cameras}
    assert torch.equal(b({**x, **cams}), b(x))  # whatever the cameras show, a blind control sees zeros
    assert json.loads((blind / "config.json").read_text())["inputs_tier"] == "vision"


def test_camera_frames_are_lerobots_frames_reduced_as_the_policy_reduces_its_cameras(camera_dataset):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    frames = camera_frames(camera_dataset, ("drone_hand", "drone_own"), 32)
    assert any((camera_dataset / ".aerobench" / "cache").glob("frames-32-*.pt"))  # the next run reads the cache
    ds = LeRobotDataset("local/x", root=camera_dataset, video_backend="pyav")
    for i in (0, 9, 10, 19):  # both episodes, first and last frames
        item = ds[i]
        for cam in ("drone_hand", "drone_own"):
            rgb = (item[f"observation.images.{cam}"] * 255).round().to(torch.uint8)[None]
            depth = torch.from_numpy(decode_depth_mm(item[f"observation.depth.{cam}"]).astype(np.int32))[None]
            assert torch.equal(frames[cam][i, :3], reduce_rgb(rgb, 32)[0])
            assert torch.equal(frames[cam][i, 3:], reduce_depth(depth, 32)[0])


def test_actions_turn_between_the_heading_and_the_world_frame_and_back():
    action = torch.tensor([[1.0, 0.0, 0.3, 0.1, -1.0], [0.2, -0.5, 0.0, 0.0, 1.0]])
    yaw = torch.tensor([math.pi / 2, -0.7])
    heading = to_heading_frame(action, yaw)
    assert torch.allclose(heading[0, :2], torch.tensor([0.0, -1.0]), atol=1e-6)  # +x seen facing +y: to the right
    assert torch.allclose(to_world_frame(heading, yaw), action, atol=1e-6)
    assert torch.equal(heading[:, 2:], action[:, 2:])


def test_egocentric_fields_read_the_proprio_state_alone():
    state = torch.zeros(2, 19)
    yaw = torch.tensor([0.3, 1.2])
    state[:, 3], state[:, 4], state[:, 6], state[:, 7] = torch.cos(yaw), torch.sin(yaw), -torch.sin(yaw), torch.cos(yaw)
    state[:, 2], state[:, 9] = 1.5, 0.4  # height, world x velocity
    start = state.clone()
    start[:, 3], start[:, 4] = 1.0, 0.0  # started facing +x
    f = ego_features(state, start, ("velocity_heading", "height", "yaw_since_start"))
    assert torch.allclose(yaw_of(state), yaw)
    assert torch.allclose(f[:, 0], 0.4 * torch.cos(yaw), atol=1e-6) and torch.allclose(f[:, 3], torch.tensor(1.5))
    assert torch.allclose(f[:, 4], torch.sin(yaw), atol=1e-6)
    assert tiers.tier_of(["observation.state", "observation.images.drone_hand", "task"]) == "vision"


def test_instruction_words_hash_the_same_in_every_process_and_a_shift_moves_pixels():
    a, b = instruction_tokens(["pick up the sugar box", "PICK up the bowl!"])
    assert a[:3].tolist() == b[:3].tolist() and a[3] != b[3] and a[4] != 0 and b[4] == 0
    assert a[:5].tolist() == [1 + __import__("zlib").crc32(w.encode()) % 4095 for w in "pick up the sugar box".split()]
    image = torch.arange(2 * 4 * 8 * 8, dtype=torch.float32).reshape(2, 4, 8, 8)
    shifted = random_shift(image, 2, torch.Generator().manual_seed(0))
    assert shifted.shape == image.shape and not torch.equal(shifted, image)
    assert torch.equal(random_shift(image, 0, torch.Generator()), image)


def test_a_blind_evaluation_renders_nothing_and_hands_the_policy_blank_cameras(camera_dataset, tmp_path, monkeypatch):
    """`aerobench eval --blind` (a LeRobot policy trained on blanked images): no camera is rendered, and the policy
    reads zeros of the cameras' shape."""
    from aerobench.eval.evaluate import EvalConfig, evaluate
    from aerobench.policies.learned import LearnedPolicy

    ckpt = _vision(camera_dataset, tmp_path / "run")
    seen = []
    act = LearnedPolicy.act
    monkeypatch.setattr(LearnedPolicy, "act", lambda self, obs: seen.append(obs["sensor_data"]) or act(self, obs))
    config = EvalConfig(policy="bc", setting="PrepareGroceries", skills=("place",), objects=("bowl",),
                        episodes_per_object=1, checkpoint=str(ckpt), max_steps=2, seed=11, blind=True)
    plan = config.resolve()
    assert not plan.record_cameras and plan.spec.blind
    with torch_threads(1):
        results = evaluate(config, tmp_path / "eval")
    assert results["provenance"]["blind"] is True and len(seen) == 2
    assert all(int(s[c]["rgb"].abs().sum()) == 0 and s[c]["rgb"].shape == (1, 128, 128, 3) for s in seen for c in s)


def test_auxiliary_targets_train_a_head_the_policy_never_reads(camera_dataset, tmp_path):
    """`--aux-fields goal_pos_body`: the task state is a training target, not an input; the tier stays `vision`."""
    from aerobench.policies.learned import load_actor

    ckpt = _vision(camera_dataset, tmp_path / "aux", aux_fields=("goal_pos_body",))
    config = json.loads((ckpt / "config.json").read_text())
    assert config["inputs_tier"] == "vision" and config["model"]["inputs"]["task_fields"] == []
    assert config["model"]["aux_dim"] == 3 and config["data"]["aux_fields"] == ["goal_pos_body"]
    actor = load_actor(ckpt)[1]
    assert actor.aux.out_features == 3
    rows = [json.loads(line) for line in (tmp_path / "aux" / "scalars.jsonl").read_text().splitlines()]
    rmse = [r["value"] for r in rows if r.get("tag") == "losses/aux_rmse"]
    assert len(rmse) == 3 and all(v > 0 for v in rmse)  # metres: the goal's offset as the inputs tell it
    with pytest.raises(ValueError, match="--aux-fields must name task state fields"):
        BCConfig(dataset="d", out="o", inputs="vision", images=True, aux_fields=("goal",))


def test_goal_keypoints_train_the_camera_cnn_to_find_the_goal_in_its_images(camera_dataset, tmp_path):
    """`--goal-keypoint-weight`: each camera's first keypoint learns the goal's image position (a label from the
    recorded state, `train.goal_pixels`); the tier stays `vision` and the loss falls as it trains."""
    from aerobench.train.bc import load_demos

    config = dict(encoder_head="keypoints", goal_keypoint_weight=1.0, film=True, learning_rate=3e-3)
    data, facts = load_demos(BCConfig(dataset=str(camera_dataset), out="o", images=True, inputs="vision",
                                      outcomes=("T",), image_size=32, **config))
    assert data["goal_xy"].shape == (len(data["action"]), 3, 2) and data["goal_visible"].any()
    assert list(facts["goal_in_view"]) == ["drone_front", "drone_hand", "drone_own"]
    ckpt = _vision(camera_dataset, tmp_path / "kp", steps=40, **config)
    assert json.loads((ckpt / "config.json").read_text())["inputs_tier"] == "vision"
    rows = [json.loads(line) for line in (tmp_path / "kp" / "scalars.jsonl").read_text().splitlines()]
    error = [r["value"] for r in rows if r.get("tag") == "losses/goal_keypoint"]
    assert len(error) == 40 and sum(error[-10:]) < sum(error[:10])
    import aux_probe  # the bench reports the goal keypoint's error on a dataset beside the auxiliary head's

    probed = _vision(camera_dataset, tmp_path / "kp_aux", aux_fields=("goal_pos_body",), **config)
    report = aux_probe.main(["--checkpoint", str(probed), "--dataset", str(camera_dataset),
                             "--train-dataset", str(camera_dataset)])
    rows = [r for cam in report["goal_keypoint_px"].values() for r in cam]
    assert rows and all(r["frames"] > 0 and r["median"] >= 0 for r in rows)
    for bad in (dict(goal_keypoint_weight=1.0), dict(goal_keypoint_weight=1.0, encoder_head="keypoints", blind=True)):
        with pytest.raises(ValueError, match="--goal-keypoint-weight needs"):
            BCConfig(dataset="d", out="o", inputs="vision", images=True, **bad)


def test_a_release_threshold_given_at_training_is_the_checkpoints_and_the_policy_acts_on_it(camera_dataset, tmp_path):
    from aerobench.policies.learned import BCPolicy

    ckpt = _vision(camera_dataset, tmp_path / "t098", close_threshold=0.98)
    assert json.loads((ckpt / "config.json").read_text())["model"]["close_threshold"] == 0.98
    assert BCPolicy.checked_config(ckpt)[1]["model"]["close_threshold"] == 0.98
    resumed = _vision(camera_dataset, tmp_path / "t098", close_threshold=0.9, steps=4)  # resumable: acting, not training
    assert json.loads((resumed / "config.json").read_text())["model"]["close_threshold"] == 0.9
    default = _vision(camera_dataset, tmp_path / "t05")
    assert "close_threshold" not in json.loads((default / "config.json").read_text())["model"]  # as before the option
    for bad in (dict(close_threshold=1.0), dict(close_threshold=0.9, gripper="continuous")):
        with pytest.raises(ValueError, match="--close-threshold must be between 0 and 1"):
            BCConfig(dataset="d", out="o", **bad)


def test_film_lets_the_instruction_change_what_the_camera_cnn_sees(camera_dataset, tmp_path):
    """`--film`: the instruction scales and shifts each convolution's channels; at initialisation it is the plain CNN
    (zero FiLM weights), and once the FiLM layer moves, two instructions give the same image different features."""
    from aerobench.policies.learned import CameraEncoder, load_actor

    ckpt = _vision(camera_dataset, tmp_path / "film", film=True, encoder_head="keypoints")
    config = json.loads((ckpt / "config.json").read_text())
    assert config["model"]["film"] is True and config["inputs_tier"] == "vision"
    actor = load_actor(ckpt)[1]
    assert actor.film.out_features == 2 * sum(config["model"]["cnn_channels"])

    torch.manual_seed(0)
    encoder = CameraEncoder(32, (8, 8), 16)
    images = torch.rand(2, 4, 32, 32)
    plain = encoder(images)
    assert torch.equal(encoder(images, torch.zeros(2, 32)), plain)  # zero FiLM: the unconditioned CNN
    film = torch.zeros(2, 32)
    film[1, :8] = 1.0  # the second sample doubles the first convolution's channels
    conditioned = encoder(images, film)
    assert torch.equal(conditioned[0], plain[0]) and not torch.allclose(conditioned[1], plain[1])
    with pytest.raises(ValueError, match="--film conditions the camera CNN on the instruction"):
        BCConfig(dataset="d", out="o", inputs="vision", film=True)  # no --images: no CNN to condition


def test_the_release_threshold_is_the_highest_that_lets_go_in_the_air_on_few_demonstrations():
    from release_calibration import lowest_in_air, per_demonstration, release_summary, release_threshold

    # two demonstrations: carried down onto the support, then the expert opens (label 0); frames after it are left out
    p = torch.tensor([0.99, 0.97, 0.95, 0.80, 0.40, 0.30, 0.10, 0.98, 0.93, 0.96, 0.90, 0.85])
    height = torch.tensor([0.30, 0.10, 0.01, 0.0, 0.0, 0.0, 0.0, 0.30, 0.05, 0.0, 0.0, 0.0])
    progress = torch.tensor([0, 0, 0, 0.1, 0.2, 0.5, 0.6, 0, 0, 0.1, 0.2, 0.5])
    label = torch.tensor([1, 1, 1, 1, 1, 0, 0, 1, 1, 1, 1, 0])
    segment = torch.tensor([0] * 7 + [1] * 5)
    demos = per_demonstration(p, progress, height, label, segment)
    assert [len(d.p_close) for d in demos] == [6, 5] and [d.expert_release for d in demos] == [5, 4]
    assert [lowest_in_air(d) for d in demos] == pytest.approx([0.97, 0.93])  # 0.95 is 1 cm up: a set-down, not a drop
    assert release_threshold([0.97, 0.93], max_early=0.0) == pytest.approx(0.929)  # strictly below the lower minimum
    assert release_threshold([0.97, 0.93], max_early=0.5) == pytest.approx(0.969)  # one of two may let go early
    summary = release_summary(demos, 0.929)
    assert summary["early_in_air"] == 0 and summary["released_on_support"] == 2 and summary["never"] == 0
    assert summary["delay_steps_median"] == -1.5  # demo 0 opens at 0.80 two steps before the expert, demo 1 one before
    high = release_summary(demos, 0.95)
    assert high["early_in_air"] == 1 and high["open_height_m_max"] == pytest.approx(0.05)  # demo 1 drops from 5 cm
    assert release_summary(demos, 0.35)["never"] == 1  # demo 1 never falls that low up to its release
    with pytest.raises(ValueError, match="calibrate on a Place dataset"):
        release_threshold([], 0.05)


def test_a_calibrated_release_is_written_into_a_copy_of_the_checkpoint_and_acted_on(camera_dataset, tmp_path):
    from release_calibration import calibrate_release

    from aerobench.policies.learned import BCPolicy

    ckpt = _vision(camera_dataset, tmp_path / "run")
    summary = calibrate_release(str(ckpt), str(camera_dataset), max_early=0.0, out=str(tmp_path / "calibrated"),
                                outcomes=("T",))
    assert summary["demonstrations"] == 2 and summary["early_in_air"] == 0  # nothing let go in the air at 0 allowed
    config = json.loads((tmp_path / "calibrated" / "config.json").read_text())
    assert config["model"]["close_threshold"] == summary["threshold"]
    assert config["model"]["release_calibration"]["max_early"] == 0.0
    assert "close_threshold" not in json.loads((ckpt / "config.json").read_text())["model"]  # the original untouched

    class Env:
        device = torch.device("cpu")

        class platform:
            action_dim = config["model"]["action_dim"]

    assert BCPolicy(Env(), str(tmp_path / "calibrated")).close_threshold == summary["threshold"]
    with pytest.raises(ValueError, match="no checkpoint at"):
        calibrate_release(str(tmp_path / "none"), str(camera_dataset))


def test_perceive_act_acts_on_the_camera_networks_estimates_in_the_vision_tier(camera_dataset, tmp_path, monkeypatch):
    """`aerobench train perceive-act`: a camera BC's auxiliary head (the perception) estimates the task-state fields a
    privileged controller was trained on; the composed policy is `vision` tier, evaluates as one, and never reads the
    env's task state. A controller reading a field the head does not estimate is refused with one line."""
    from aerobench.envs.skills.base import AeroSkillEnv
    from aerobench.eval.evaluate import EvalConfig, evaluate
    from aerobench.policies.perceive_act import PerceiveActPolicy
    from aerobench.train.perceive_act import head_scale

    perception = _vision(camera_dataset, tmp_path / "perception", aux_fields=("goal_pos_body", "is_grasp_confirmed"),
                         encoder_head="keypoints", goal_keypoint_weight=1.0)
    assert "aux_mean" in json.loads((perception / "normalization.json").read_text())  # the head's scale is saved
    controller = train_bc(BCConfig(dataset=str(camera_dataset), out=str(tmp_path / "controller"), steps=2,
                                   batch_size=8, outcomes=("T",), hidden=(16,), progress=False, inputs="privileged",
                                   task_fields=("goal_pos_body", "is_grasp_confirmed"), ego_fields=("height",),
                                   action_frame="heading"))
    out = tmp_path / "pa"
    compose = ("train", "perceive-act", "--perception", str(perception), "--controller", str(controller),
               "--keypoint-camera", "drone_hand", "--far-keypoint-cameras", "drone_front,drone_own",
               "--keypoint-gate-m", "0", "--keypoint-spread-max", "0.3", "--goal-memory", "--depth-z")
    proc = aerobench_here(*compose, "--out", str(tmp_path / "unmeasured"))  # no fixture frame is within 5 cm
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1
    assert "--depth-z cannot be measured there" in proc.stderr
    monkeypatch.setattr("aerobench.train.perceive_act.DEPTH_Z_WITHIN_M", 100.0)  # every frame counts as near
    proc = aerobench_here(*compose, "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    composed = json.loads((out / "config.json").read_text())
    assert composed["keypoint_gate_m"] is None and composed["goal_memory"] and composed["keypoint_spread_max"] == 0.3
    assert set(composed["depth_z"]) == {"sugar_box", "bowl"}  # the fixture's objects, on the perception's own data:
    # no starts added
    assert not (out / "starts.json").exists()
    assert PerceiveActPolicy.input_tier(str(out)) == "vision"
    assert PerceiveActPolicy.needs_images(str(out))
    older = tmp_path / "older_perception"  # a checkpoint saved before the head's scale was: recomputed from its data
    shutil.copytree(perception, older)
    saved = json.loads((older / "normalization.json").read_text())
    (older / "normalization.json").write_text(json.dumps({k: v for k, v in saved.items() if not k.startswith("aux_")}))
    mean, std = head_scale(older, str(camera_dataset))
    assert np.allclose(mean, saved["aux_mean"], atol=1e-5) and np.allclose(std, saved["aux_std"], atol=1e-5)

    acting, env_task_state, act = [], AeroSkillEnv.task_state, PerceiveActPolicy.act

    def guarded_task_state(self):  # the recorder reads it between steps; the policy, while acting, must not
        assert not acting, "perceive_act read the env's task state"
        return env_task_state(self)

    def counted_act(self, obs):
        acting.append(True)
        try:
            return act(self, obs)
        finally:
            acting.pop()

    with monkeypatch.context() as patch, torch_threads(1):
        patch.setattr(AeroSkillEnv, "task_state", guarded_task_state)
        patch.setattr(PerceiveActPolicy, "act", counted_act)
        results = evaluate(EvalConfig(policy="perceive_act", setting="PrepareGroceries", skills=("place",),
                                      objects=("sugar_box",), episodes_per_object=1, checkpoint=str(out), max_steps=3,
                                      seed=11, inputs="vision"), tmp_path / "eval")
    assert results["inputs"] == "vision" and results["cells"][0]["n"] == 1
    wider = train_bc(BCConfig(dataset=str(camera_dataset), out=str(tmp_path / "wider"), steps=1, batch_size=8,
                              outcomes=("T",), hidden=(16,), progress=False, task_fields=("goal_pos_body", "progress")))
    proc = aerobench_here("train", "perceive-act", "--perception", str(perception), "--controller", str(wider),
                          "--out", str(tmp_path / "refused"))
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1
    assert "reads progress, which the perception does not estimate" in proc.stderr
    proc = aerobench_here("train", "perceive-act", "--perception", str(perception), "--controller", str(controller),
                          "--goal-memory", "--out", str(tmp_path / "refused"))
    assert proc.returncode == 2 and "give --keypoint-camera too" in proc.stderr
    import perceive_probe  # the bench that measures the estimate against the task state, per distance

    report = perceive_probe.main(["--checkpoint", str(out), "--dataset", str(camera_dataset)])
    assert report["head"] and report["fused"] and set(report["keypoint"]) == {"drone_front", "drone_hand", "drone_own"}
    assert report["spread_max"] == 0.3 and set(report["keypoint_concentrated"]) == set(report["keypoint"])
    assert all(a is None or 0 <= a <= 1 for a in report["spread_auroc_goal_in_view"].values())
    assert all(r["frames"] > 0 and r["rms_m"] >= 0 and r["vertical_rms_m"] >= 0 for r in report["head"])


def test_perception_noise_offsets_what_the_policy_reads_and_marks_its_results(camera_dataset, tmp_path):
    """`bench/perception_noise.py`: a diagnostic evaluation whose policy reads `goal_pos_body` off by a per-episode
    offset (and chosen fields as 0); its results say so, and the process acts as before afterwards."""
    import perception_noise

    from aerobench.policies.observer import ActorObserver

    controller = train_bc(BCConfig(dataset=str(camera_dataset), out=str(tmp_path / "c"), steps=1, batch_size=8,
                                   outcomes=("T",), hidden=(16,), progress=False,
                                   task_fields=("goal_pos_body", "heading_error")))
    plain = ActorObserver.observe
    with torch_threads(1):
        code = perception_noise.run(["--sigma-m", "0.02", "--blank", "heading_error", "--policy", "bc",
                                     "--checkpoint", str(controller), "--setting", "PrepareGroceries", "--skills",
                                     "place", "--objects", "sugar_box", "--episodes-per-object", "1", "--max-steps",
                                     "3", "--seed", "11", "--out", str(tmp_path / "e")])
    assert code == 0 and ActorObserver.observe is plain
    provenance = json.loads((tmp_path / "e" / "results.json").read_text())["provenance"]
    assert "sigma 0.02 m" in provenance["diagnostic"] and "heading_error read as 0" in provenance["diagnostic"]
    assert provenance["command"].startswith("python bench/perception_noise.py --sigma-m 0.02 --blank heading_error")
    assert perception_noise.run(["--policy", "bc"]) == 2  # no --sigma-m: refused
