"""Training of aerobench's own learned skill policies, CleanRL style (one readable file per algorithm).

- `bc`: behaviour cloning on successful demonstrations of an exported dataset (`train_bc(BCConfig(...))`).
- `ppo`: PPO on the batched skill envs, from scratch or from a BC checkpoint (`train_ppo(PPOConfig(...))`).
- `rewards`: the per-skill reward (task progress, success, penalties), defined once.
- `common`: seeding, scalar logs, resume checks, CLI flags from the config dataclasses.

Both write checkpoints that `aerobench eval --policy bc|ppo --checkpoint DIR` loads (`aerobench.policies.learned`).
"""
