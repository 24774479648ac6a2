"""Optional real assets: a clear one-line error when missing; YCB-layout meshes load and rest on supports."""

import gymnasium as gym
import pytest
import torch
import trimesh

import aerobench.envs  # noqa: F401
from aerobench.envs.assets import MissingAssetError, ycb_model_dir


def test_missing_ycb_names_the_path_and_the_fetch_command(tmp_path):
    with pytest.raises(MissingAssetError) as e:
        gym.make("AeroPick-v1", object="sugar_box", real_assets="ycb", assets_dir=str(tmp_path)).reset(seed=0)
    message = str(e.value)
    assert str(tmp_path / "assets" / "mani_skill2_ycb" / "models" / "004_sugar_box") in message
    assert "python -m mani_skill.utils.download_asset ycb" in message and "\n" not in message


def test_missing_replicacad_is_one_line(tmp_path):
    with pytest.raises(MissingAssetError, match=r"ReplicaCAD not found at .*download_asset ReplicaCAD"):
        gym.make("AeroPick-v1", real_assets="replicacad", assets_dir=str(tmp_path))


def test_unknown_asset_kind():
    with pytest.raises(ValueError, match="unknown real asset kind 'shapenet'; valid kinds: ycb, replicacad"):
        gym.make("AeroPick-v1", real_assets="shapenet")


def test_ycb_layout_meshes_are_used_and_rest_on_the_support(tmp_path):
    folder = tmp_path / "assets" / "mani_skill2_ycb" / "models" / "004_sugar_box"
    folder.mkdir(parents=True)
    mesh = trimesh.creation.box(extents=(0.038, 0.089, 0.175))
    mesh.apply_translation((0.3, -0.2, 0.5))  # off-centre like a raw scan: the loader recentres it
    mesh.export(folder / "collision.ply")
    mesh.export(folder / "textured.obj")
    assert ycb_model_dir("sugar_box", tmp_path) == folder
    env = gym.make(
        "AeroPick-v1", obs_mode="state_dict", object="sugar_box", num_distractors=0, real_assets="ycb", assets_dir=str(tmp_path)
    )
    env.reset(seed=0)
    base = env.unwrapped
    rest = float(base.evaluators[0].rest_z[0])
    action = torch.zeros(5)
    action[-1] = 1.0
    for _ in range(10):
        _, _, _, _, info = env.step(action)
    assert abs(float(info["object_height"][0]) - rest) < 0.01 and bool(info["is_object_upright"][0])
    env.close()
