"""How far a PPO run's training episodes get, by interactions: read while it runs, or after.

`aerobench train ppo` appends every finished training episode to `RUN/train_episodes.jsonl` with its outcome and its
peak progress potential (`aerobench.train.rewards.potential`). Before the first success, the success rate says
nothing about whether a run is learning; the peak potential does. For Pick it is minus the closest the tool centre
point came to the grasp point, and above 0.5 once the object was grasped. This script prints, per bin of
interactions:

- the episodes that ended in it, their successes, and the share truncated by the time limit and ending in a collision;
- the median episode length;
- the median peak potential: for Pick, the median closest approach in cm, the share of episodes within 5 cm, and
  the episodes that grasped.

With `--png` it also draws the spec's PPO curve: training success as a moving average over the last 400 episodes
(spec Fig. `learning_curves`) against interactions, with the median peak potential beside it.

Where the run logged its updates (`RUN/scalars.jsonl`), it also prints per bin the median approximate KL between the
policy that collected a window and the one its update left (the mean over the update's minibatches), the share of
samples whose probability ratio was clipped, and the action std: a run whose std shrinks while its learning rate stays
fixed takes ever larger steps, which `--target-kl` bounds.

`--gripper-probe K` (Pick) runs K episodes with the run's checkpoint as training acts (sampled actions, new starts
from seed 777) and prints, by distance of the tool centre point to the grasp point, the median probability the actor
gives "close" and its median vertical command: whether it arrives with the gripper open and lifts once it holds.

    python bench/ppo_progress.py RUN [--bins 0,50000,100000,...] [--png RUN/progress.png] [--gripper-probe 8]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from learning_curves import moving_average, ppo_training_episodes  # noqa: E402

SPEC_WINDOW = 400  # the spec's moving-average window (Fig. learning_curves)
NEAR_M = 0.05
GRASPED_POTENTIAL = 0.5  # Pick's potential is -distance + grasped + 2 x lift: above this only while grasped
UPDATE_TAGS = {"losses/approx_kl": "approx_kl", "losses/clipfrac": "clipfrac", "charts/action_std": "action_std",
               "charts/learning_rate": "learning_rate"}


def default_bins(last_step: int) -> list[int]:
    """Bin edges: 50k wide up to 200k, 100k wide up to 1M, then 500k wide, up to the last logged step."""
    edges, step = [0], 0
    while step < last_step:
        step += 50_000 if step < 200_000 else 100_000 if step < 1_000_000 else 500_000
        edges.append(step)
    return edges


def skill_of(run: Path) -> str | None:
    """The run's skill, from its checkpoint's config (None where the run has not written one yet)."""
    path = run / "checkpoint" / "config.json"
    return json.loads(path.read_text())["train"]["skill"] if path.is_file() else None


def progress_rows(episodes: list[dict], edges: list[int], skill: str | None) -> list[dict]:
    """One summary per bin `(edges[i], edges[i + 1]]` of global steps that has episodes."""
    rows = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        chunk = [e for e in episodes if lo < e["global_step"] <= hi]
        if not chunk:
            continue
        outcomes = Counter(e.get("outcome", "?") for e in chunk)
        n = len(chunk)
        row = {"from": lo, "to": hi, "episodes": n, "successes": sum(bool(e["success"]) for e in chunk),
               "truncated": outcomes["truncated"] / n, "collision": outcomes["collision"] / n,
               "median_length": statistics.median(e["length"] for e in chunk), "outcomes": dict(outcomes.most_common())}
        peaks = [e["peak_potential"] for e in chunk if "peak_potential" in e]
        if peaks:
            row["median_peak_potential"] = statistics.median(peaks)
            if skill == "pick":
                row["median_closest_m"] = max(-row["median_peak_potential"], 0.0)
                row["within_5cm"] = sum(p > -NEAR_M for p in peaks) / len(peaks)
                row["grasped"] = sum(p > GRASPED_POTENTIAL for p in peaks)
        rows.append(row)
    return rows


def update_rows(run: Path, edges: list[int]) -> list[dict]:
    """Per bin of global steps with logged updates: their number and the median of each of `UPDATE_TAGS`."""
    from aerobench.train.common import read_scalars

    values = {tag: read_scalars(run, tag) for tag in UPDATE_TAGS}
    rows = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        row: dict = {"from": lo, "to": hi}
        for tag, name in UPDATE_TAGS.items():
            chunk = [v for step, v in values[tag] if lo < step <= hi]
            if chunk:
                row[name], row["updates"] = statistics.median(chunk), len(chunk)
        if "updates" in row:
            rows.append(row)
    return rows


def format_row(row: dict) -> str:
    text = (f"{row['from'] / 1000:>6g}k-{row['to'] / 1000:g}k  {row['episodes']:5d} episodes, {row['successes']:4d} "
            f"successes, truncated {100 * row['truncated']:5.1f}%, collision {100 * row['collision']:5.1f}%, "
            f"median length {row['median_length']:5.0f}")
    if "median_closest_m" in row:
        text += (f", median closest {100 * row['median_closest_m']:5.1f} cm, within 5 cm "
                 f"{100 * row['within_5cm']:5.1f}%, grasped {row['grasped']}")
    elif "median_peak_potential" in row:
        text += f", median peak potential {row['median_peak_potential']:.3f}"
    return text


def plot(episodes: list[dict], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    steps = np.array([e["global_step"] for e in episodes], float)
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.plot(steps, moving_average(np.array([float(e["success"]) for e in episodes]), SPEC_WINDOW), color="C1",
            label=f"training success ({SPEC_WINDOW}-episode moving average)")
    ax.set_ylim(-0.03, 1.03)
    ax.set_xlabel("environment interactions")
    ax.set_ylabel("success")
    if all("peak_potential" in e for e in episodes):
        twin = ax.twinx()
        twin.plot(steps, moving_average(np.array([e["peak_potential"] for e in episodes]), SPEC_WINDOW),
                  color="C0", alpha=0.7, label="peak progress potential (moving average)")
        twin.set_ylabel("peak progress potential")
        twin.legend(fontsize=7, loc="lower right")
    ax.legend(fontsize=7, loc="upper left")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


PROBE_SEED = 777
PROBE_BANDS = ((0.10, math.inf, "farther than 10 cm, not grasped"), (0.03, 0.10, "3-10 cm, not grasped"),
               (0.0, 0.03, "within 3 cm, not grasped"))


def gripper_probe(run: Path, episodes: int) -> list[dict]:
    """Per step of `episodes` sampled Pick episodes of the run's checkpoint: distance to the grasp point, grasped,
    the actor's probability of "close", the sent vertical command (normalized) and the object's lift."""
    import torch

    from aerobench.policies.learned import load_actor, load_weights
    from aerobench.policies.observer import ActorObserver
    from aerobench.train.ppo import PPOConfig
    from aerobench.train.ppo_rollout import SkillEnv, sample_action

    checkpoint = run / "checkpoint"
    meta, actor, normalizer = load_actor(checkpoint)
    model, train = meta["model"], meta["train"]
    if train["skill"] != "pick" or model["gripper"] != "binary":
        raise ValueError("--gripper-probe reads a Pick run with the binary gripper")
    log_std = load_weights(checkpoint)["log_std"]
    config = PPOConfig(setting=train["setting"], skill="pick", out=str(run), seed=PROBE_SEED, objects=train["objects"],
                       platform=train["platform"], controller=train["controller"],
                       max_episode_steps=train["max_episode_steps"], progress=False)
    env = SkillEnv(config, "state_dict", 1)
    observer, steps = ActorObserver(model), []
    torch.manual_seed(PROBE_SEED)
    for _ in range(episodes):
        obs, _ = env.reset_all()
        observer.reset(torch.arange(1))
        done = False
        while not done:
            raw = observer.observe(env.env.unwrapped, obs)
            x = {**raw, "state": normalizer.state(raw["state"])}
            out, _, _, sent = sample_action(actor, x, log_std, normalizer, "binary")
            obs, _, terminated, truncated, info = env.env.step(sent)
            steps.append({"distance": float(info["tcp_to_grasp_point"][0]), "grasped": bool(info["is_grasped"][0]),
                          "p_close": float(torch.sigmoid(out[0, -1])), "vz": float(sent[0, 2]),
                          "lift": float(info["lift_height"][0])})
            done = bool(terminated[0] | truncated[0])
    env.close()
    return steps


def probe_rows(steps: list[dict]) -> list[dict]:
    """The probe's steps summarized per distance band, then the grasped ones."""
    groups = [(label, [s for s in steps if not s["grasped"] and lo <= s["distance"] < hi]) for lo, hi, label in PROBE_BANDS]
    groups.append(("grasped", [s for s in steps if s["grasped"]]))
    return [{"group": label, "steps": len(sel), "p_close": statistics.median(s["p_close"] for s in sel),
             "vz": statistics.median(s["vz"] for s in sel), "max_lift_m": max(s["lift"] for s in sel)}
            for label, sel in groups if sel]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="the PPO run folder (aerobench train ppo --out)")
    parser.add_argument("--bins", help="comma-separated global-step edges (default: 50k, then 100k, then 500k wide)")
    parser.add_argument("--png", type=Path, help="also draw the training-success curve here")
    parser.add_argument("--gripper-probe", type=int, default=0, metavar="K",
                        help="Pick: also run K sampled episodes of the checkpoint and print where it closes and lifts")
    args = parser.parse_args(argv)
    try:
        episodes = ppo_training_episodes(args.run)
    except ValueError as e:
        parser.error(str(e))
    if not episodes:
        parser.error(f"{args.run / 'train_episodes.jsonl'} has no finished episode yet")
    edges = [int(v) for v in args.bins.split(",")] if args.bins else default_bins(episodes[-1]["global_step"])
    skill = skill_of(args.run)
    print(f"{args.run}: {len(episodes)} episodes to step {episodes[-1]['global_step']}, skill {skill or 'unknown'}")
    for row in progress_rows(episodes, edges, skill):
        print(format_row(row))
    updates = update_rows(args.run, edges)
    if updates:
        print("updates (medians per bin):")
    for row in updates:
        print(f"{row['from'] / 1000:>6g}k-{row['to'] / 1000:g}k  {row['updates']:5d} updates, approx KL "
              f"{row.get('approx_kl', math.nan):.3f}, clipped {100 * row.get('clipfrac', math.nan):4.1f}%, action std "
              f"{row.get('action_std', math.nan):.3f}, learning rate {row.get('learning_rate', math.nan):.2e}")
    if args.png:
        plot(episodes, args.png, f"{args.run.name}: {skill or ''} PPO, {episodes[-1]['global_step']} interactions")
        print(f"wrote {args.png}")
    if args.gripper_probe > 0:
        steps = gripper_probe(args.run, args.gripper_probe)
        print(f"gripper probe: {args.gripper_probe} sampled episodes, {len(steps)} steps (seed {PROBE_SEED})")
        for row in probe_rows(steps):
            print(f"  {row['group']:<32} {row['steps']:5d} steps, p(close) median {row['p_close']:.2f}, vertical "
                  f"command median {row['vz']:+.2f}, object lifted up to {100 * row['max_lift_m']:.1f} cm")


if __name__ == "__main__":
    main()
