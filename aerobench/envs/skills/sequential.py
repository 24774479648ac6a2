"""AeroSequential-v1: a task setting's skill chain flown continuously in one episode (spec "Long-Horizon").

Each env keeps a subtask pointer; the active stage's evaluator scores the step, and its success hands over to the
next stage (whose trackers start then). Per-stage success is reported as `subtask_<k>_success`.
"""

from __future__ import annotations

import torch
from mani_skill.utils.registration import register_env

from ..tasks import chain_instruction
from .articulation import ArticulationEvaluator
from .base import AeroSkillEnv
from .nav import NavEvaluator
from .pick import PickEvaluator
from .place import PlaceEvaluator

NAV_ABOVE_PLACE_ANCHOR_M = 0.5  # a chain's Nav ends this far above the next placement's anchor


@register_env("AeroSequential-v1", max_episode_steps=4000)
class AeroSequentialEnv(AeroSkillEnv):
    """**Task description.** The setting's chain, e.g. PackageDelivery: pick the package from the vehicle, fly to the
    building entrance, place it on the cabinet by the door; LongHorizonRearrangement: open the fridge or drawer,
    pick, fly, place (and close). Args: `setting`, `chain` (default: the setting's first), `object`, `platform`.

    **Randomizations.** As the skill envs: layout, materials, lights, object, supports and goals of every stage,
    fixture states (closed when the chain opens them), and a start 0.5-1 m from the first stage's target (in
    front of the handle, within 60 deg of the door's normal, when the chain begins with Open or Close).

    **Success conditions.** Every stage's own success, in order. **Fails** when the active stage fails or the flight
    envelope is left. Episodes are 4000 control steps (200 s).
    """

    skill = "sequential"

    def __init__(self, *args, chain: str | None = None, **kwargs):
        self.chain_name = chain
        super().__init__(*args, **kwargs)

    def _check_setting(self) -> None:
        self.chain_name, self.chain = self.setting.chain(self.chain_name)
        self.uses_object = any(s.skill in ("pick", "place") for s in self.chain)

    def _default_platform(self) -> str:
        return self.setting.chain_platform

    def _make_evaluators(self):
        evaluators, carrying, last_pick = [], False, None
        for subtask in self.chain:
            if subtask.skill == "pick":
                last_pick = PickEvaluator(self, subtask.where)
                evaluators.append(last_pick)
                carrying = True
            elif subtask.skill == "place":
                evaluators.append(PlaceEvaluator(self, subtask.where, after_pick=last_pick))
                carrying = False
            elif subtask.skill == "nav":
                evaluators.append(NavEvaluator(self, subtask.where, carrying=carrying))
            else:
                evaluators.append(ArticulationEvaluator(self, subtask.skill, subtask.where))
        self.stage = torch.zeros(self.num_envs, dtype=torch.long, device=self.device)
        return evaluators

    def _handle_links(self):
        links = []
        for ev in getattr(self, "evaluators", []):
            if isinstance(ev, ArticulationEvaluator):
                links += [link for link in ev.handle_links() if link not in links]
        return links

    def active_evaluator_index(self):
        return self.stage.clamp(max=len(self.evaluators) - 1)

    def _sample_episode(self, env_idx):
        ok = torch.ones(len(env_idx), dtype=torch.bool, device=self.device)
        for k, ev in enumerate(self.evaluators):
            if isinstance(ev, PickEvaluator):
                ok &= ev.sample(env_idx)
            elif isinstance(ev, PlaceEvaluator):
                ok &= ev.sample_goal(env_idx)
            elif isinstance(ev, ArticulationEvaluator):
                ok &= ev.sample(env_idx, opens_later=any(
                    isinstance(e, ArticulationEvaluator) and e.skill == "open" for e in self.evaluators[:k]
                ))
        for k, ev in enumerate(self.evaluators):
            if isinstance(ev, NavEvaluator):
                later = next((e for e in self.evaluators[k + 1:] if isinstance(e, PlaceEvaluator)), None)
                if ev.where or later is None:
                    ok &= ev.sample_target(env_idx)
                else:
                    target = later.anchor(env_idx) + torch.tensor([0.0, 0.0, NAV_ABOVE_PLACE_ANCHOR_M], device=self.device)
                    names = [later.instruction(i).split(" on ", 1)[-1] for i in env_idx.tolist()]
                    ev.set_target(env_idx, target, [f"above {n}" for n in names])
        if self.target is not None:  # clear of the object and of where the chain will set it down
            goals = [ev.goal[env_idx] for ev in self.evaluators if isinstance(ev, PlaceEvaluator)]
            self.place_distractors(env_idx, [self.target.pose.p[env_idx], *goals], self.setting.pick_supports)
        first = self.evaluators[0]
        min_tcp = first.min_start_tcp_height(env_idx) if isinstance(first, PickEvaluator) else torch.full(
            (len(env_idx),), -1e9, device=self.device
        )
        position, yaw, free = self.sample_start(
            env_idx,
            first.anchor(env_idx),
            min_tcp,
            face_anchor=isinstance(first, ArticulationEvaluator),
            from_airframe=isinstance(first, NavEvaluator),
            within_cone=first.start_cone(env_idx) if isinstance(first, ArticulationEvaluator) else None,
        )
        self.set_drone(env_idx, position, yaw)
        self.stage[env_idx] = 0
        for ev in self.evaluators:
            ev.begin(env_idx)
        for i in env_idx.tolist():
            self.instructions[i] = chain_instruction([ev.instruction(i) for ev in self.evaluators])
        return ok & free

    def _overall_success(self, active_success):
        done = len(self.evaluators)
        advance = active_success & (self.stage < done)
        if advance.any():
            self.stage = torch.where(advance, self.stage + 1, self.stage)
            moved = advance.nonzero()[:, 0]
            for k in range(1, done):
                rows = moved[self.stage[moved] == k]
                if len(rows):
                    self.evaluators[k].begin(rows)
        return self.stage >= done

    def evaluate(self):
        info = super().evaluate()
        for k in range(len(self.evaluators)):
            info[f"subtask_{k}_success"] = self.stage > k
        info["subtask_index"] = self.stage.clone()
        return info
