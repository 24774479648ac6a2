"""The packed depth codec: exact in memory, and exact through a real LeRobot dataset (PNG in parquet) and back."""

import os

import numpy as np
import pytest
import torch

from aerobench.depth import decode_depth_mm, encode_depth_mm

os.environ.setdefault("HF_HUB_OFFLINE", "1")
MAX_MM = 10_000  # the range: within 1 mm up to 10 m


def random_depth(seed: int, shape=(128, 128)) -> np.ndarray:
    depth = np.random.default_rng(seed).integers(0, MAX_MM + 1, shape, dtype=np.uint16)
    depth[0, :4] = [0, 1, 255, 256]  # byte boundaries and "no return"
    depth[1, :2] = [MAX_MM, np.iinfo(np.uint16).max]
    return depth


def test_packing_layout():
    packed = encode_depth_mm(np.array([[0, 1, 256, 10_000, 1_999]], dtype=np.uint16))
    assert packed.dtype == np.uint8 and packed.shape == (1, 5, 3)
    # 10000 = 39 * 256 + 16; B: 20 mm a level, saturating at 255 (5.1 m)
    assert packed[0].tolist() == [[0, 0, 0], [0, 1, 0], [1, 0, 12], [39, 16, 255], [7, 207, 99]]


def test_the_blue_channel_is_a_linear_depth_picture_and_the_decode_ignores_it():
    depth = random_depth(1)
    packed = encode_depth_mm(depth)
    assert np.array_equal(packed[..., 2], np.minimum(depth // 20, 255))
    before_the_blue_channel = packed.copy()
    before_the_blue_channel[..., 2] = 0  # datasets written before it hold B = 0
    assert np.array_equal(decode_depth_mm(before_the_blue_channel), depth)


def test_round_trip_uint8_and_lerobot_float_forms():
    depth = random_depth(0)
    packed = encode_depth_mm(depth[..., None])  # (H, W, 1) is accepted too
    assert np.array_equal(decode_depth_mm(packed), depth)
    as_lerobot = torch.from_numpy(packed).permute(2, 0, 1).float() / 255.0  # what LeRobotDataset returns
    assert np.array_equal(decode_depth_mm(as_lerobot), depth)
    batch = torch.stack([as_lerobot, as_lerobot])
    assert decode_depth_mm(batch).shape == (2, 128, 128)


def test_bad_inputs_are_rejected():
    with pytest.raises(ValueError, match="uint16"):
        encode_depth_mm(np.zeros((4, 4), dtype=np.float32))
    with pytest.raises(ValueError, match="shape"):
        encode_depth_mm(np.zeros((4, 4, 2), dtype=np.uint16))
    with pytest.raises(ValueError):
        decode_depth_mm(np.zeros((4, 4, 3), dtype=np.int32))


def test_round_trip_through_a_lerobot_dataset(tmp_path):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from aerobench.export.features import IMAGE_NAMES, depth_key

    key = depth_key("drone_hand")
    features = {key: {"dtype": "image", "shape": (128, 128, 3), "names": IMAGE_NAMES}}
    root = tmp_path / "depth"
    dataset = LeRobotDataset.create("local/depth", 20, features, root=root, use_videos=False)
    depths = [random_depth(seed) for seed in range(3)]
    for depth in depths:
        dataset.add_frame({key: encode_depth_mm(depth), "task": "look"})
    dataset.save_episode()
    dataset.finalize()

    loaded = LeRobotDataset("local/depth", root=root)
    for i, depth in enumerate(depths):
        assert np.array_equal(decode_depth_mm(loaded[i][key]), depth)


def test_the_batched_torch_packing_is_the_numpy_one():
    """`pack_depth` (a policy adapter's per-step form, on the env's device) packs exactly as `encode_depth_mm`."""
    from aerobench.depth import pack_depth

    depth = torch.tensor([[[0, 19, 20, 255], [256, 5099, 5100, 65535]], [[1, 300, 70000, -5], [10_000, 1, 2, 3]]],
                         dtype=torch.int32)  # (2, 2, 4), with values out of range on both sides
    packed = pack_depth(depth)
    assert packed.dtype == torch.uint8 and packed.shape == (2, 2, 4, 3)
    for d, p in zip(depth, packed):
        expected = encode_depth_mm(d.clamp(0, 65535).numpy().astype(np.uint16))
        assert np.array_equal(p.numpy(), expected)
