"""`aerobench publish`: an eval's results file into a leaderboard folder, with rollout videos of the row's own starts.

A results file names its videos relative to itself, so a row's videos travel with it: `publish` copies the eval's
`results.json` to `DEST` (e.g. `leaderboards/results/TidyHouse_expert.json`) and its mp4s to `DEST`'s sibling folder
`<stem>_videos/`. The videos may come from a second, small eval (`--videos-from`): `aerobench eval --video N` with
the same policy, checkpoint, setting and `--seed` plays the same first plan indices (episode i runs with
`seed * 1_000_003 + i`, and the plan's first cells do not depend on `--episodes-per-object`), so a 360-episode
state-only row gets its videos from a few rendered episodes. Each video must show one of the row's own starts with
the row's outcome; anything else is refused with one line.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from .compare import run_from_results
from .results import load_results, write_results

VIDEO_NAME = re.compile(r"episode_(\d+)\.mp4$")


def _check_same_policy(row: dict, other: dict, source: Path) -> None:
    for what, a, b in (("setting", row["setting"], other["setting"]), ("policy", row["policy"], other["policy"]),
                       ("checkpoint", row["provenance"].get("checkpoint"), other["provenance"].get("checkpoint")),
                       ("--seed", row["provenance"].get("seed"), other["provenance"].get("seed")),
                       ("chain", row["provenance"].get("chain"), other["provenance"].get("chain")),
                       ("max steps", row["provenance"].get("max_steps"), other["provenance"].get("max_steps")),
                       ("contact solver", row["provenance"].get("physx_solver"), other["provenance"].get("physx_solver"))):
        if a != b:
            raise ValueError(f"the videos of {source} are of another run ({what} {b!r}, the row's {a!r}): make them "
                             f"with the row's eval command plus --video N")


def publish(eval_dir: str | Path, dest: str | Path, videos_from: str | Path | None = None) -> dict:
    """Copy `eval_dir`'s results to `dest` with the videos of `videos_from` (default: its own); returns the document."""
    eval_dir, dest = Path(eval_dir), Path(dest)
    if dest.suffix != ".json":
        raise ValueError(f"--to must name a .json results file (e.g. leaderboards/results/TidyHouse_expert.json), got {dest}")
    row_file = eval_dir / "results.json" if eval_dir.is_dir() else eval_dir
    results = load_results(row_file)
    source = Path(videos_from) if videos_from is not None else eval_dir
    source_dir = source if source.is_dir() else source.parent
    other = results if videos_from is None else load_results(source_dir / "results.json")
    if videos_from is not None:
        _check_same_policy(results, other, source_dir)
    row_episodes = run_from_results(row_file, results).episodes  # {index: (seed, skill, object, outcome)}
    video_episodes = run_from_results(row_file if videos_from is None else source_dir / "results.json", other).episodes
    videos = []
    for rel in other.get("videos", []):
        match = VIDEO_NAME.search(rel)
        if match is None or not (source_dir / rel).is_file():
            raise ValueError(f"{source_dir / rel} is missing or not an episode video: re-run the eval with --video N")
        index = int(match.group(1))
        if row_episodes.get(index) != video_episodes.get(index):
            raise ValueError(f"video {rel} (episode {index}: {video_episodes.get(index)}) is not the row's episode "
                             f"{index} ({row_episodes.get(index)}): the same start must end the same way in both runs")
        videos.append((index, source_dir / rel))
    folder = dest.with_name(dest.stem + "_videos")
    staging = folder.with_name(folder.name + ".tmp")  # the videos may be the published row's own: copy, then swap
    shutil.rmtree(staging, ignore_errors=True)
    published = dict(results)
    if videos:
        staging.mkdir(parents=True)
        for index, path in sorted(videos):
            shutil.copyfile(path, staging / f"episode_{index:06d}.mp4")
        published["videos"] = [f"{folder.name}/episode_{index:06d}.mp4" for index, _ in sorted(videos)]
        if videos_from is not None:
            published["provenance"] = {**results["provenance"], "videos_command": other["provenance"].get("command")}
    else:
        published.pop("videos", None)
    shutil.rmtree(folder, ignore_errors=True)
    if videos:
        staging.rename(folder)
    write_results(dest, published)
    return published
