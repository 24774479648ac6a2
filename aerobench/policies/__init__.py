"""Policies by name behind one batched interface: `policy.reset(env_idx)`, `policy.act(obs) -> (N, A)` actions.

`make_policy(name, env, checkpoint=None)` builds one for a (possibly batched) aerobench env. Registered now:
`expert` (the privileged hybrid expert, `aerobench.expert`) and `random`. Learned policies (BC, PPO and the LeRobot
policies ACT, Diffusion, pi0, pi0.5) register here too as they land.
"""

from .registry import POLICIES, Policy, make_policy, policy_needs_images, register_policy

__all__ = ["POLICIES", "Policy", "make_policy", "policy_needs_images", "register_policy"]
