"""Are the Open / Close expert's labels a function of what the BC sees? Per expert phase, how well a small MLP
predicts the expert's action from the DAgger BC's inputs alone, and from them plus one more reading: the airframe
velocity, the velocity loop's integral xi (the expert's drive converts the acceleration it wants into a velocity
command through xi), or the finger positions (the pinch is a closing sequence).

    python bench/label_predictability.py [--skill close] [--episodes 24] [--held-out 6] [--seed 11] [--out DIR]

The expert flies `--episodes` noise-free episodes of PrepareGroceries (the frames are saved and reused); an MLP
(256-256, `--steps` Adam steps) is fitted per input set on all but the last `--held-out` episodes and scored on those:
R^2 of the flight command (vx, vy, vz) and the fraction of frames whose gripper command it gets the wrong sign of.
A low R^2 or a high gripper error in a phase, which one more reading raises or lowers, says what that phase's labels
depend on that the BC does not see (docs/experiments.md, "Close: what the labels depend on").
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

from dagger import ARTICULATION_FIELDS  # noqa: E402

from aerobench.envs.observations import (  # noqa: E402
    ARM_STATE_FIELDS,
    STATE_FIELDS,
    field_slices,
    task_state_fields,
)

BC_FIELDS = tuple(ARTICULATION_FIELDS.split(","))
# what each input set adds to the BC's task-state fields: (source, field) pairs
EXTRA = {
    "velocity": (("task", "linear_velocity"),),
    "velocity_integral": (("xi", None),),
    "finger_position": (("proprio", "finger_position"),),
}
INPUT_SETS = {"bc": (), **{f"bc+{k}": v for k, v in EXTRA.items()}, "bc+all": sum(EXTRA.values(), ())}
FLIGHT = slice(0, 3)  # the normalized velocity command (vx, vy, vz) in the action


def collect(skill: str, episodes: int, seed: int, max_steps: int = 900) -> dict[str, np.ndarray]:
    """Fly the expert noise-free for `episodes` episodes (seeds as the rollout runner's episode seeds); per control
    step the task state, proprio state, velocity integral xi, the expert's phase, the episode index and the action."""
    import gymnasium as gym
    import torch

    import aerobench.envs  # noqa: F401
    from aerobench.expert import ExpertController
    from aerobench.rollout.runner import SEED_STRIDE

    env = gym.make(f"Aero{skill.capitalize()}-v1", obs_mode="state_dict", setting="PrepareGroceries")
    base, rows = env.unwrapped, {k: [] for k in ("task", "proprio", "xi", "phase", "episode", "action", "success")}
    try:
        for e in range(episodes):
            env.reset(seed=seed * SEED_STRIDE + e, options={"reconfigure": True})
            controller = ExpertController(base)
            controller.reset(torch.arange(1))
            expert = controller.experts[0]
            for _ in range(max_steps):
                rows["task"].append(base.task_state()[0].cpu().numpy())
                rows["proprio"].append(base.agent.get_proprioception()["state"][0].cpu().numpy())
                rows["xi"].append(base.agent.body_controller.memory.xi[0].cpu().numpy())
                action = controller.act()
                rows["phase"].append(int(expert.phase[0]))
                rows["episode"].append(e)
                rows["action"].append(action[0].cpu().numpy())
                _, _, terminated, truncated, info = env.step(action)
                if bool(terminated[0]) or bool(truncated[0]):
                    break
            rows["success"].extend([bool(info["success"][0])] * (len(rows["episode"]) - len(rows["success"])))
    finally:
        env.close()
    return {k: np.asarray(v, dtype=np.float32 if k in ("task", "proprio", "xi", "action") else np.int64)
            for k, v in rows.items()}


# the layouts of the recorded task and proprio rows (the arm platform's, which the Open / Close experts fly)
LAYOUT = {"task": field_slices(task_state_fields(with_arm=True)), "proprio": field_slices(STATE_FIELDS + ARM_STATE_FIELDS)}


def inputs(frames: dict[str, np.ndarray], extra: tuple) -> np.ndarray:
    """The BC's task-state fields, plus `extra`'s readings, as one `(T, D)` matrix."""
    parts = [frames["task"][:, LAYOUT["task"][f]] for f in BC_FIELDS]
    for source, name in extra:
        parts.append(frames["xi"] if source == "xi" else frames[source][:, LAYOUT[source][name]])
    return np.concatenate(parts, axis=1)


def fit_predict(x: np.ndarray, y: np.ndarray, train: np.ndarray, steps: int, seed: int) -> np.ndarray:
    """An MLP (256-256, inputs standardized on the training rows) fitted by MSE on `train`; its predictions for all."""
    import torch

    torch.manual_seed(seed)
    mean, std = x[train].mean(0), x[train].std(0) + 1e-6
    xs = torch.tensor((x - mean) / std, dtype=torch.float32)
    ys = torch.tensor(y, dtype=torch.float32)
    net = torch.nn.Sequential(torch.nn.Linear(x.shape[1], 256), torch.nn.ReLU(), torch.nn.Linear(256, 256),
                              torch.nn.ReLU(), torch.nn.Linear(256, y.shape[1]))
    optimizer = torch.optim.Adam(net.parameters(), lr=1e-3)
    rows = torch.nonzero(torch.as_tensor(train)).squeeze(1)
    for _ in range(steps):
        batch = rows[torch.randint(0, len(rows), (256,))]
        loss = ((net(xs[batch]) - ys[batch]) ** 2).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    with torch.no_grad():
        return net(xs).numpy()


def r_squared(prediction: np.ndarray, label: np.ndarray) -> float | None:
    """1 - residual / total sum of squares over every column; None without spread to explain."""
    total = float(((label - label.mean(0)) ** 2).sum())
    return None if total < 1e-9 else 1.0 - float(((prediction - label) ** 2).sum()) / total


def score(prediction: np.ndarray, frames: dict[str, np.ndarray], rows: np.ndarray, phase_names: dict[int, str]) -> dict:
    """Per phase of the rows: frames, flight-command R^2, and the gripper's wrong-sign fraction."""
    out = {}
    for code, name in phase_names.items():
        m = rows & (frames["phase"] == code)
        if not m.any():
            continue
        label = frames["action"][m]
        out[name] = {"frames": int(m.sum()), "flight_r2": r_squared(prediction[m, FLIGHT], label[:, FLIGHT]),
                     "gripper_wrong": float((np.sign(prediction[m, -1]) != np.sign(label[:, -1])).mean())}
    return out


def measure(frames: dict[str, np.ndarray], held_out: int, steps: int, phase_names: dict[int, str]) -> dict:
    episodes = int(frames["episode"].max()) + 1
    if not 0 < held_out < episodes:
        raise ValueError(f"--held-out must be between 1 and {episodes - 1} (the episodes flown less one)")
    train = frames["episode"] < episodes - held_out
    return {name: score(fit_predict(inputs(frames, extra), frames["action"], train, steps, seed=0), frames, ~train,
                        phase_names) for name, extra in INPUT_SETS.items()}


def table(results: dict) -> str:
    first = next(iter(results.values()))
    phases = list(first)
    lines = ["| inputs | " + " | ".join(f"{p} ({first[p]['frames']} frames): R^2 / gripper wrong" for p in phases) + " |",
             "| --- |" + " --- |" * len(phases)]
    for name, per_phase in results.items():
        cells = []
        for p in phases:
            s = per_phase.get(p)
            r2 = "-" if s is None or s["flight_r2"] is None else f"{s['flight_r2']:.3f}"
            cells.append("-" if s is None else f"{r2} / {s['gripper_wrong']:.1%}")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--skill", choices=("open", "close"), default="close")
    p.add_argument("--episodes", type=int, default=24)
    p.add_argument("--held-out", type=int, default=6, help="the last this many episodes are scored, not fitted")
    p.add_argument("--seed", type=int, default=11, help="the episodes' seed (as aerobench generate --seed)")
    p.add_argument("--steps", type=int, default=4000, help="Adam steps per fit")
    p.add_argument("--max-steps", type=int, default=900, help="control steps per episode at most")
    p.add_argument("--out", type=Path, default=Path("outputs/bench/label_predictability"))
    args = p.parse_args(argv)
    if args.episodes < 2 or args.steps < 1:
        p.error("--episodes must be at least 2 and --steps at least 1")
    from aerobench.expert.articulation import ArticulationPhase

    args.out.mkdir(parents=True, exist_ok=True)
    cache = args.out / f"frames_{args.skill}_seed{args.seed}_{args.episodes}x{args.max_steps}.npz"
    if cache.is_file():
        frames = dict(np.load(cache))
    else:
        frames = collect(args.skill, args.episodes, args.seed, args.max_steps)
        np.savez(cache, **frames)
    phase_names = {int(ph): ph.name.lower() for ph in ArticulationPhase}
    results = measure(frames, args.held_out, args.steps, phase_names)
    summary = {"skill": args.skill, "episodes": args.episodes, "held_out": args.held_out, "seed": args.seed,
               "steps": args.steps, "expert_success": float(frames["success"][np.r_[True, np.diff(frames["episode"]) != 0]].mean()),
               "bc_fields": BC_FIELDS, "results": results}
    path = args.out / f"label_predictability_{args.skill}.json"
    path.write_text(json.dumps(summary, indent=1))
    print(table(results))
    print(f"wrote {path}")
    return summary


if __name__ == "__main__":
    main()
