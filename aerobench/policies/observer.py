"""What a learned actor reads at each control step, built one way for acting (`learned.LearnedPolicy`) and for PPO's
collection (`train.ppo_rollout.Collector`): the selected numbers with their history, the cameras, the instruction;
and the env action from the actor's output (turned into the world frame where the policy acts in its heading
frame, `egocentric`).

Per env it remembers the first state of the episode (or chain stage: a chained evaluation resets a stage's policy
when the stage begins) for `yaw_since_start`, and the instruction's word ids, both renewed on `reset`. The
instruction is the active skill's (`AeroSkillEnv.skill_instruction`): what a per-skill policy was trained with.

Everything stays on the actor's `device` (the env's, for `LearnedPolicy` on physx_cuda): a control step copies
nothing to the host and reads no tensor value; only a reset's instruction lookup (per env, by index) does.
"""

from __future__ import annotations

import torch

from .camera_input import as_network_input, camera_images
from .egocentric import to_world_frame, yaw_of
from .inputs import FrameHistory, InputSpec
from .instruction import instruction_tokens


class ActorObserver:
    """Raw (unnormalized) actor inputs from an aerobench env's observations, for a checkpoint's `model` spec."""

    def __init__(self, model: dict, device: torch.device | str = "cpu"):
        self.device = torch.device(device)
        self.inputs = InputSpec.from_dict(model["inputs"])
        self.cameras = () if model.get("blind") else tuple(model["cameras"])
        self.image_size = model["image_size"]
        self.history = FrameHistory(self.inputs.history)
        self.start: torch.Tensor | None = None  # (N, S) each env's first state of its episode or stage
        self.tokens: torch.Tensor | None = None  # (N, W) each env's instruction word ids
        self.fresh: torch.Tensor | None = None  # (N,) envs reset since their last observation
        self.renewed = True  # whether any env was reset since the last observation (a host flag: no tensor read)

    def reset(self, env_idx: torch.Tensor) -> None:
        """Episodes (or chain stages) restart in `env_idx`: history, first state and instruction are renewed."""
        self.history.reset(env_idx)
        self.renewed = True
        if self.fresh is not None:
            self.fresh[env_idx.to(self.device)] = True

    def observe(self, env, obs: dict, keep: bool = True) -> dict[str, torch.Tensor]:
        """The actor's raw inputs `{"state", <camera>..., "instruction"}` for the current observation; `keep`: the
        frame enters the history (a value bootstrap peeks without keeping it)."""
        state = obs["agent"]["state"].to(self.device)
        n = state.shape[0]
        if self.fresh is None or len(self.fresh) != n:
            self.fresh = torch.ones(n, dtype=torch.bool, device=self.device)
            self.start, self.tokens, self.renewed = state.clone(), None, True
        if self.inputs.needs_start:
            self.start = torch.where(self.fresh[:, None], state, self.start)
        if self.inputs.instruction and self.renewed:  # at resets only: the instruction is looked up per env
            rows = list(range(n)) if self.tokens is None else self.fresh.nonzero()[:, 0].tolist()
            tokens = instruction_tokens([env.skill_instruction(i) for i in rows]).to(self.device)
            self.tokens = tokens if self.tokens is None else \
                self.tokens.index_put_((torch.tensor(rows, device=self.device),), tokens)
        task_state = env.task_state().to(self.device) if self.inputs.reads_task_state else None
        frame = self.inputs.frame(state, task_state, self.start)
        out = {"state": self.history.push(frame) if keep else self.history.peek(frame)}
        if keep:
            self.fresh[:] = False
            self.renewed = False
        images = camera_images(obs, self.cameras, self.image_size)
        out.update({cam: as_network_input(x.to(self.device)) for cam, x in images.items()})
        if self.inputs.instruction:
            out["instruction"] = self.tokens
        return out

    def to_env(self, action: torch.Tensor, obs: dict) -> torch.Tensor:
        """The env's world-frame action `(N, A)` in [-1, 1] from the policy's (`action_frame`)."""
        if self.inputs.action_frame == "heading":
            action = to_world_frame(action, yaw_of(obs["agent"]["state"].float().to(action.device)))
        return action.clamp(-1.0, 1.0)
