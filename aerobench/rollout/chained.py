"""The spec's chained evaluation protocol (appendix "Failure Analysis"): error propagation across skill boundaries.

A setting's chain (e.g. pick -> nav -> place) is flown in one `AeroSequential-v1` episode. The evaluated policy acts
the skill stages; the shared privileged expert flies every transport (nav) stage, so differences in transport
outcome reflect the state the preceding pick left. Each stage has a step budget, and during transport the grasp counts
as held while both fingers exceed 0.1 N (the env's `is_grasp_held`) and the tool centre point stays within 6 cm of the
planned grasp point (`tcp_to_grasp_point`); four consecutive violations end the transport as a dropped object.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from ..annotation.failure_analysis import HOLD_MAX_VIOLATIONS, HOLD_RADIUS_M
from ..envs.checks import FailureCause
from ..envs.tasks import TaskSetting, get_setting

TRANSPORT = "transport"  # the protocol's name for a nav stage flown by the shared expert
# Spec appendix "Failure Analysis", Protocol: pick <= 400 control steps, transport <= 1200, place <= 1000. Open and
# Close are not in the protocol; they keep their skill envs' episode length (AeroOpen-v1 / AeroClose-v1).
STAGE_MAX_STEPS = {"pick": 400, "nav": 1200, "place": 1000, "open": 1200, "close": 1200}


def stage_skills(stages: Sequence[str]) -> tuple[str, ...]:
    return tuple("nav" if s == TRANSPORT else s for s in stages)


def resolve_chain(setting: str | TaskSetting, stages: Sequence[str]) -> str:
    """The setting's chain whose stages are `stages` (`transport` names its nav stage), e.g. pick,transport,place.
    `setting` is its name or the setting itself (an evaluation resolves it once)."""
    spec = get_setting(setting) if isinstance(setting, str) else setting
    wanted = stage_skills(stages)
    for name, chain in spec.chains.items():
        if tuple(s.skill for s in chain) == wanted:
            return name
    valid = [",".join(TRANSPORT if s.skill == "nav" else s.skill for s in chain) for chain in spec.chains.values()]
    raise ValueError(f"{spec.name} has no chain {','.join(stages)}; valid --chain values: {'; '.join(valid) or 'none'}")


def split_checkpoints(checkpoint: str | None) -> dict[str, str | None]:
    """`--checkpoint DIR` (one for every learned stage) or `pick=DIR,place=DIR` (one per skill) -> {skill or '*': DIR}."""
    if not checkpoint or "=" not in checkpoint:
        return {"*": checkpoint}
    out = {}
    for part in checkpoint.split(","):
        skill, sep, path = part.partition("=")
        if not sep or not skill.strip() or not path.strip():
            raise ValueError(f"--checkpoint {checkpoint!r}: give one folder, or skill=FOLDER pairs like pick=A,place=B")
        out[skill.strip()] = path.strip()
    return out


def checkpoint_for(checkpoints: dict[str, str | None], skill: str) -> str | None:
    if skill in checkpoints:
        return checkpoints[skill]
    if "*" in checkpoints:
        return checkpoints["*"]
    raise ValueError(f"--checkpoint names no folder for {skill} (it has {', '.join(checkpoints)}); "
                     f"add {skill}=DIR or give one folder for every skill")


class ChainedPolicy:
    """The evaluated policy on the skill stages, the shared expert on transport stages, switching as the env's stage
    pointer advances (the incoming stage's policy is reset for those envs, e.g. clearing an action-chunk queue).
    `checkpoints` is `split_checkpoints`' mapping: {skill or '*': DIR}."""

    def __init__(self, env, policy: str, checkpoints: dict[str, str | None] | None = None):
        from ..expert import ExpertController
        from ..policies import make_policy

        self.env, self.name = env, policy
        self.skills = [ev.skill for ev in env.evaluators]
        self.expert = ExpertController(env)  # transport; also keeps its stage bookkeeping on every step
        checkpoints = checkpoints if checkpoints is not None else {"*": None}
        self.stage_policies: list = []
        built: dict[str | None, object] = {}
        for skill in self.skills:
            if skill == "nav":
                self.stage_policies.append(None)
                continue
            path = checkpoint_for(checkpoints, skill) if policy != "expert" else None
            if path not in built:  # one model serves every stage it is given for (loaded once)
                built[path] = make_policy(policy, env, checkpoint=path)
            self.stage_policies.append(built[path])
        self.stage = torch.zeros(env.num_envs, dtype=torch.long, device=env.device)

    def reset(self, env_idx: torch.Tensor) -> None:
        self.stage[env_idx] = 0
        self.expert.reset(env_idx)
        for policy in {id(p): p for p in self.stage_policies if p is not None}.values():
            policy.reset(env_idx)

    def act(self, obs) -> torch.Tensor:
        active = self.env.active_evaluator_index()
        entered = (active != self.stage).nonzero()[:, 0]
        for k in active[entered].unique().tolist():
            policy = self.stage_policies[k]
            if policy is not None:
                policy.reset(entered[active[entered] == k])
        self.stage = active.clone()
        action = self.expert.act()
        for k, policy in enumerate(self.stage_policies):
            rows = active == k
            if policy is not None and rows.any():
                action = torch.where(rows[:, None], policy.act(obs).to(action.device), action)
        return action

    def infeasible(self) -> torch.Tensor:
        """Starts the expert cannot plan, when the expert flies the first stage (the protocol's expert reference)."""
        first = self.stage_policies[0]
        if first is not None and hasattr(first, "infeasible"):
            return first.infeasible()
        return torch.zeros(self.env.num_envs, dtype=torch.bool, device=self.env.device)


class ChainMonitor:
    """Per-env stage step counts and the transport grasp-hold check, updated after every control step."""

    def __init__(self, skills: Sequence[str], num_envs: int, device: torch.device | str = "cpu"):
        self.skills = list(skills)
        self.limits = torch.tensor([STAGE_MAX_STEPS[s] for s in self.skills], device=device)
        self.is_transport = torch.tensor([s == "nav" for s in self.skills], device=device)
        self.stage = torch.zeros(num_envs, dtype=torch.long, device=device)
        self.stage_steps = torch.zeros(num_envs, dtype=torch.long, device=device)
        self.violations = torch.zeros(num_envs, dtype=torch.long, device=device)

    def update(self, info: dict) -> tuple[torch.Tensor, torch.Tensor]:
        """(over_budget, grasp_lost) `(N,)` bools after a step; `info` holds the step's signals on the env's device."""
        acting = self.stage
        self.stage_steps += 1
        stage_now = info["subtask_index"].long().clamp(max=len(self.skills) - 1)
        moved = stage_now != acting
        if "is_grasp_held" in info:
            violation = ~info["is_grasp_held"].bool() | (info["tcp_to_grasp_point"] > HOLD_RADIUS_M)
        else:
            violation = torch.zeros_like(moved)
        in_transport = self.is_transport[acting] & ~moved
        self.violations = torch.where(in_transport & violation, self.violations + 1, torch.zeros_like(self.violations))
        grasp_lost = self.violations >= HOLD_MAX_VIOLATIONS
        over_budget = ~moved & (self.stage_steps >= self.limits[acting]) & ~grasp_lost
        self.stage_steps = torch.where(moved, torch.zeros_like(self.stage_steps), self.stage_steps)
        self.stage = stage_now
        return over_budget, grasp_lost


def mark_grasp_lost(signals: dict, rows: torch.Tensor) -> None:
    """Record a transport ended by the hold check as the Nav table's object-drop failure in the step's signals."""
    cause = signals["fail_cause"]
    first = rows & (cause == 0)
    signals["fail_cause"] = torch.where(first, torch.full_like(cause, int(FailureCause.OBJECT_DROP)), cause)
    signals["fail"] = signals["fail"] | rows
