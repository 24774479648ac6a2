"""The privileged hybrid expert: batched per-skill controllers over the env's privileged state.

`ExpertController(env)` builds one expert per evaluator of a skill env (or per stage of a sequential env) and acts
for all envs at once. Skills: `pick`, `place`, `nav` (with the route `planner`), `articulation` (open/close on the
arm platform). The expert demonstrates; it is not an evaluated policy (spec Sec. 3.3.1).
"""

from __future__ import annotations

import torch

from ..envs.skills.pick import ENCLOSED_KINDS
from .look import LookFirst
from .nav import NavExpert
from .pick import PickExpert
from .place import PlaceExpert


def _expert_for(env, evaluator, carrying: bool, after_stage: bool, following=None, previous=None):
    skill = evaluator.skill
    if skill == "pick":
        return PickExpert(env, evaluator, after_stage=after_stage)
    if skill == "place":
        return PlaceExpert(env, evaluator)
    if skill == "nav":
        # a held object hangs its grasp height below the tool centre point
        depth = float(env.target_grasp_point[:, 2].max()) if carrying and env.target is not None else 0.0
        after_pick = previous if previous is not None and previous.skill == "pick" else None
        return NavExpert(env, evaluator, carrying_depth=depth, after_pick=after_pick)
    from .articulation import ArticulationExpert

    reach_in_next = following is not None and following.skill == "pick" and bool(set(following.kinds) & set(ENCLOSED_KINDS))
    return ArticulationExpert(env, evaluator, reach_in_next=reach_in_next)


class ExpertController:
    """Acts for every env of a skill or sequential env; chains switch expert when the env's stage advances.
    `look_first`: a Pick skill's expert first turns on the spot to face its object (`look.LookFirst`)."""

    def __init__(self, env, look_first: bool = False):
        if not hasattr(env, "evaluators"):  # e.g. AeroFly-v1, the flight test: no task for an expert to solve
            raise ValueError(f"the expert acts in the skill and task envs (AeroPick-v1, ...), not in {type(env).__name__}: "
                             "drive it with velocity commands instead")
        self.env = env
        carrying, self.experts = False, []
        for k, evaluator in enumerate(env.evaluators):
            following = env.evaluators[k + 1] if k + 1 < len(env.evaluators) else None
            previous = env.evaluators[k - 1] if k else None
            self.experts.append(
                _expert_for(env, evaluator, carrying, after_stage=bool(self.experts), following=following,
                            previous=previous)
            )
            carrying = evaluator.skill == "pick" or (carrying and evaluator.skill != "place")
        if look_first:
            if len(self.experts) != 1:
                raise ValueError("--look-first demonstrates the Pick skill alone, not a chain")
            self.experts[0] = LookFirst(self.experts[0])
        self.stage = torch.zeros(env.num_envs, dtype=torch.long, device=env.device)

    def reset(self, env_idx: torch.Tensor) -> None:
        self.stage[env_idx] = 0
        self.experts[0].reset(env_idx)

    def act(self) -> torch.Tensor:
        if len(self.experts) == 1:  # a single skill: one stage, never changed (a few ops less per control step)
            return self.experts[0].act()
        active = self.env.active_evaluator_index()
        changed = active != self.stage
        if changed.any():
            for k, expert in enumerate(self.experts):
                rows = (changed & (active == k)).nonzero()[:, 0]
                if len(rows):
                    expert.reset(rows)
            self.stage = active.clone()
        actions = torch.stack([expert.act() for expert in self.experts], dim=0)
        return actions[active, torch.arange(self.env.num_envs, device=self.env.device)]

    def infeasible(self) -> torch.Tensor:
        """Envs whose first stage has no planned route: starts the expert rejects (recorded as initialization
        failures, apart from executed episodes). Call right after `reset`."""
        planned = getattr(self.experts[0], "planned", None)
        return torch.zeros_like(self.stage, dtype=torch.bool) if planned is None else ~planned

    def phase(self) -> torch.Tensor:
        phases = torch.stack([expert.phase for expert in self.experts], dim=0)
        return phases[self.stage, torch.arange(self.env.num_envs, device=self.env.device)]


def phase_name(skill: str, code: int) -> str | None:
    """The name of the expert's phase `code` in `skill` ("descend"), None for -1 (no expert phase recorded)."""
    if code < 0:
        return None
    from .articulation import ArticulationPhase
    from .nav import NavPhase
    from .pick import PickPhase
    from .place import PlacePhase

    phases = {"pick": PickPhase, "place": PlacePhase, "nav": NavPhase, "open": ArticulationPhase,
              "close": ArticulationPhase}[skill]
    return phases(code).name.lower() if code in phases._value2member_map_ else f"phase {code}"
