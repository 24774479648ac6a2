"""Policies by name behind one batched interface: `policy.reset(env_idx)`, `policy.act(obs) -> (N, A)` actions.

`make_policy(name, env, checkpoint=None)` builds one for a (possibly batched) aerobench env: `expert` (the
privileged hybrid expert, `aerobench.expert`), `random`, `bc` and `ppo` (`learned`: checkpoints of `aerobench train`)
and the LeRobot policies `act`, `diffusion`, `pi0`, `pi05` (`lerobot_policies`; tiny pi variants in `pi_tiny`, made
with `aerobench pi-init`) and `perceive_act` (`perceive_act`: a camera network's estimates of the task state,
acted on by a state controller).
"""

from .registry import POLICIES, Policy, make_policy, policy_needs_images, register_policy

# the policies register themselves by name on import (after the registry they register in)
from . import builtin, learned, lerobot_policies, perceive_act  # noqa: E402,F401  isort: skip

__all__ = ["POLICIES", "Policy", "make_policy", "policy_needs_images", "register_policy"]
