"""`aerobench` from the shell: every command's help, `fly`'s one-line errors, JSON output, video and plot files.
The error checks run `main` in this process (tests/cli_here.py); `fly` and `render` run from the shell."""

import json
import os
import subprocess
import sys

import pytest

from tests.cli_here import aerobench_here

CLI = [sys.executable, "-m", "aerobench.cli"]


def _run(*args, timeout=300):
    env = dict(os.environ, HF_HUB_OFFLINE="1", MS_SKIP_ASSET_DOWNLOAD_PROMPT="1")
    return subprocess.run(CLI + list(args), capture_output=True, text=True, timeout=timeout, env=env)


def _commands(parser) -> dict:
    """Every (sub)command path of the parser, e.g. ('dataset', 'info'), with its parser."""
    import argparse

    found = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                found[(name,)] = sub
                found.update({(name, *k): v for k, v in _commands(sub).items()})
    return found


def test_every_command_has_a_help_page(capsys):
    """`--help` formats every command's options (a literal % in a help text once broke `aerobench --help`)."""
    from aerobench.cli import build_parser

    parser = build_parser()
    commands = _commands(parser)
    assert {("fly",), ("demo",), ("render",), ("generate",), ("dataset", "info"), ("eval",), ("summarize",),
            ("compare",), ("plan",), ("leaderboard",), ("train", "bc"), ("train", "ppo"), ("pi-init",)} <= set(commands)
    for path in [(), *commands]:
        with pytest.raises(SystemExit) as stop:
            parser.parse_args([*path, "--help"])
        assert stop.value.code == 0, path
        assert "usage: aerobench" in capsys.readouterr().out


@pytest.mark.parametrize(
    "args, message",
    [
        (["--platform", "hexa"], "aerobench fly: error: unknown platform 'hexa'; valid platforms: gripper, arm"),
        (["--scenario", "loop"], "aerobench fly: error: unknown scenario 'loop'; valid scenarios: hover, step, square, payload, reference"),
        (["--controller", "pid"], "aerobench fly: error: unknown controller 'pid'; valid controllers: payload-aware, nominal"),
        (["--seconds", "-3"], "aerobench fly: error: --seconds must be a positive number, got -3.0"),
        (["--seconds", "nan"], "aerobench fly: error: --seconds must be a positive number, got nan"),
        (["--payload-kg", "9"], "aerobench fly: error: --payload-kg must be between 0 and 1.5 kg, got 9.0"),
        (["--seconds", "abc"], "aerobench fly: error: argument --seconds: invalid float value: 'abc'"),
    ],
)
def test_bad_input_is_one_line(args, message):
    r = aerobench_here("fly", *args)
    assert r.returncode == 2
    assert r.stderr.strip() == message
    assert "Traceback" not in r.stderr


def test_hover_json_video_and_plot(tmp_path):
    video, plot = tmp_path / "hover.mp4", tmp_path / "hover.png"
    r = _run("fly", "--platform", "gripper", "--scenario", "hover", "--seconds", "1", "--json", "--video", str(video), "--plot", str(plot))
    assert r.returncode == 0, r.stderr
    metrics = json.loads(r.stdout.strip().splitlines()[-1])
    assert {"max_drift_m", "max_tilt_deg"} <= set(metrics)
    assert metrics["scenario"] == "hover" and metrics["seconds"] == pytest.approx(1.0)
    assert video.stat().st_size > 1000 and plot.stat().st_size > 1000


def test_render_writes_the_views_picture(tmp_path):
    out = tmp_path / "pick.png"
    r = _run("render", "--env", "AeroPick-v1", "--setting", "PrepareGroceries", "--object", "bowl", "--out", str(out))
    assert r.returncode == 0, r.stderr
    import imageio.v2 as imageio

    from aerobench.envs.views import TILE

    picture = imageio.imread(out)
    views = 2 * TILE + 34  # RGB and depth rows of the three cameras, the depth scale; the third-person view as wide
    assert picture.shape[1] == views + 3 * TILE and picture.shape[0] > views  # the instruction strip on top
    assert picture.std() > 5


@pytest.mark.parametrize(
    "args, message",
    [
        (["--env", "AeroDance-v1"], "aerobench render: error: unknown env 'AeroDance-v1'; valid envs: AeroPick-v1, AeroPlace-v1, AeroNav-v1, AeroOpen-v1, AeroClose-v1, AeroSequential-v1, AeroFly-v1"),
        (["--setting", "PrepareGroceries", "--object", "cracker_box"], "aerobench render: error: object 'cracker_box' is not part of PrepareGroceries; its objects are: master_chef_can, sugar_box, tomato_soup_can, tuna_fish_can, pudding_box, gelatin_box, potted_meat_can, bowl"),
    ],
)
def test_render_bad_names(tmp_path, args, message):
    r = aerobench_here("render", *args, "--out", str(tmp_path / "x.png"))
    assert r.returncode == 2 and r.stderr.strip() == message
