"""pi0 and pi0.5 on CPU, offline: aerobench's tokenizer, the tiny random variants, and the whole path
`aerobench pi-init --variant tiny` -> `lerobot-train --config_path configs/<p>_tidy_house.json --policy.path DIR`
-> a checkpoint -> `aerobench eval --policy <p> --checkpoint DIR`. Also: missing local weights or tokenizer folders
are one-line errors that say what to put where."""

import json
import shutil
import sys
from pathlib import Path

import pytest
import torch
from safetensors.torch import load_file

from aerobench.cli import main as aerobench_main
from aerobench.envs.objects import ALL_OBJECTS
from aerobench.envs.tasks import instruction, object_phrase
from aerobench.policies.pi_init import PiInitConfig, init_pi
from aerobench.policies.pi_tiny import PI05TinyConfig
from aerobench.policies.pi_tokenizer import save_tokenizer

from .smoke_eval import eval_two_short_picks

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


def test_tokenizer_loads_offline_from_its_folder_and_pads_like_lerobot_asks(tmp_path):
    from lerobot.processor import TokenizerProcessorStep
    from transformers import AutoTokenizer

    folder = save_tokenizer(tmp_path / "tok")
    tok = AutoTokenizer.from_pretrained(folder)  # HF_HUB_OFFLINE=1 (tests/conftest.py): a folder, no hub
    text = instruction("pick", obj="tomato_soup_can", where="the kitchen counter")
    out = tok([text, "fly to the lobby"], max_length=16, truncation=True, padding="max_length", padding_side="right",
              return_tensors="pt")
    ids, mask = out["input_ids"], out["attention_mask"]
    assert ids.shape == (2, 16)
    assert (ids[:, 0] == tok.bos_token_id).all() and tok.pad_token_id == 0
    assert mask[0].sum() == 1 + len(text.split()) and mask[1].sum() == 5  # one token per known word, after <bos>
    assert (ids[mask == 0] == 0).all() and not mask[0, mask[0].sum():].any()  # padded on the right
    assert tok.decode(ids[0], skip_special_tokens=True) == text
    assert tok.unk_token_id not in ids
    # every object name and pi0.5's state bins are whole words; anything else still encodes, by characters
    words = {w for name in ALL_OBJECTS for w in object_phrase(name).split()} | {"Task", "State", "255", "Action"}
    assert all(len(tok(w, add_special_tokens=False)["input_ids"]) == 1 for w in words)
    assert tok.unk_token_id not in tok("Xylophone 3.5 m/s!")["input_ids"]
    assert len(tok) <= PI05TinyConfig().vocab_size
    # LeRobot's tokenizer step loads it by folder name, as a saved preprocessor does
    step = TokenizerProcessorStep(tokenizer_name=str(folder), max_length=48)
    assert step.get_config()["tokenizer_name"] == str(folder)
    assert (save_tokenizer(tmp_path / "again") / "tokenizer.json").read_text() == (folder / "tokenizer.json").read_text()


def _one_line_error(argv: list[str], capsys) -> str:
    assert aerobench_main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    return err


def test_missing_local_weights_or_tokenizer_are_one_line_errors(tmp_path, capsys):
    base = ["pi-init", "--policy", "pi05", "--dataset", str(tmp_path / "ds"), "--out", str(tmp_path / "out")]
    weights, tokenizer = tmp_path / "pi05_base", tmp_path / "paligemma"
    err = _one_line_error([*base, "--weights", str(weights), "--tokenizer", str(tokenizer)], capsys)
    assert f"weights folder {weights} lacks config.json, model.safetensors" in err and "lerobot/pi05_base" in err

    weights.mkdir()
    (weights / "config.json").write_text("{}")
    (weights / "model.safetensors").write_bytes(b"")
    err = _one_line_error([*base, "--weights", str(weights), "--tokenizer", str(tokenizer)], capsys)
    assert f"tokenizer folder {tokenizer}" in err and "tokenizer.json or tokenizer.model" in err
    assert "google/paligemma-3b-pt-224" in err

    err = _one_line_error(base, capsys)
    assert "--weights DIR" in err and "--variant tiny" in err
    err = _one_line_error([*base, "--variant", "huge"], capsys)
    assert "unknown variant 'huge'; valid: pretrained, tiny" in err
    assert not (tmp_path / "out").exists()


def test_tiny_init_saves_weights_that_load_back_and_a_hub_tokenizer_fails_offline_in_one_line(camera_dataset, tmp_path):
    from lerobot.policies.factory import get_policy_class

    from aerobench.policies.lerobot_policies import _load_config, load_policy

    out = init_pi(PiInitConfig(policy="pi05", dataset=str(camera_dataset), out=str(tmp_path / "tiny"), variant="tiny"))
    config = _load_config(out, "pi05")
    assert config.type == "pi05_tiny" and Path(config.tokenizer_name) == out / "tokenizer"
    assert set(config.input_features) == {"observation.state", *(f"observation.images.{c}" for c in
                                                                  ("drone_front", "drone_hand", "drone_own"))}
    # LeRobot's from_pretrained falls back to random weights on any load error: check the saved ones arrive
    model = get_policy_class(config.type).from_pretrained(out, config=config, local_files_only=True)
    saved = load_file(out / "model.safetensors")
    state = model.state_dict()
    assert saved and all(torch.equal(state[k], v) for k, v in saved.items())
    assert 1e5 < sum(p.numel() for p in model.parameters()) < 5e6

    moved = shutil.copytree(out, tmp_path / "hub_tokenizer")
    pre = json.loads((moved / "policy_preprocessor.json").read_text())
    for step in pre["steps"]:
        if step["registry_name"] == "tokenizer_processor":
            step["config"]["tokenizer_name"] = "google/paligemma-3b-pt-224"
    (moved / "policy_preprocessor.json").write_text(json.dumps(pre))
    with pytest.raises(ValueError, match="'google/paligemma-3b-pt-224', which is not a local folder") as e:
        load_policy(moved, "pi05")
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("policy", ["pi0", "pi05"])
def test_tiny_pi_trains_with_the_repo_config_and_evaluates(policy, camera_dataset, run_offline, tmp_path):
    init_dir, train_dir = tmp_path / "init", tmp_path / "train"
    # `aerobench pi-init` in this process (a subprocess paid 10-15 s of imports); lerobot-train and eval run as the user runs them
    assert aerobench_main(["pi-init", "--policy", policy, "--variant", "tiny", "--dataset", str(camera_dataset),
                           "--out", str(init_dir)]) == 0
    run_offline([str(BIN / "lerobot-train"), "--config_path", str(REPO / "configs" / f"{policy}_tidy_house.json"),
                 "--policy.path", str(init_dir), "--policy.device", "cpu", "--dataset.root", str(camera_dataset),
                 "--steps", "2", "--save_freq", "2", "--batch_size", "2", "--num_workers", "0",
                 "--output_dir", str(train_dir)], cwd=tmp_path)
    checkpoint = train_dir / "checkpoints" / "last" / "pretrained_model"
    config = json.loads((checkpoint / "config.json").read_text())
    assert config["type"] == f"{policy}_tiny" and config["dtype"] == "bfloat16"  # the repo config's settings apply
    pre = json.loads((checkpoint / "policy_preprocessor.json").read_text())
    (tokenizer_step,) = [s for s in pre["steps"] if s["registry_name"] == "tokenizer_processor"]
    assert tokenizer_step["config"]["tokenizer_name"] == str(init_dir / "tokenizer")
    assert not torch.equal(*(load_file(d / "model.safetensors")["model.action_out_proj.weight"]
                             for d in (init_dir, checkpoint)))  # two optimizer steps moved the weights

    label = f"{policy} tiny (2 steps, test)"
    eval_two_short_picks(policy, train_dir, label, tmp_path)


def test_pretrained_route_links_local_weights_and_points_the_processors_at_the_local_tokenizer(camera_dataset,
                                                                                              tmp_path):
    """`--variant pretrained` with a local weights folder (a tiny one stands in for lerobot/pi05_base, which is
    several GB and not available offline) and a local tokenizer folder."""
    from aerobench.policies.lerobot_policies import load_policy

    weights = init_pi(PiInitConfig(policy="pi05", dataset=str(camera_dataset), out=str(tmp_path / "base"),
                                   variant="tiny", seed=3))
    tokenizer = save_tokenizer(tmp_path / "my_tokenizer")
    out = init_pi(PiInitConfig(policy="pi05", dataset=str(camera_dataset), out=str(tmp_path / "ft"),
                               weights=str(weights), tokenizer=str(tokenizer)))
    assert (out / "model.safetensors").resolve() == weights / "model.safetensors"  # linked, not copied
    pre = json.loads((out / "policy_preprocessor.json").read_text())
    (step,) = [s for s in pre["steps"] if s["registry_name"] == "tokenizer_processor"]
    assert step["config"]["tokenizer_name"] == str(tokenizer.resolve())
    config, model, preprocess, _ = load_policy(out, "pi05")
    assert config.input_features["observation.state"].shape == (19,)
    saved = load_file(weights / "model.safetensors")
    assert all(torch.equal(model.state_dict()[k], v) for k, v in saved.items())
    with pytest.raises(ValueError, match="holds a 'pi05_tiny' checkpoint, not 'pi0'; use --policy pi05"):
        init_pi(PiInitConfig(policy="pi0", dataset=str(camera_dataset), out=str(tmp_path / "wrong"),
                             weights=str(weights), tokenizer=str(tokenizer)))
