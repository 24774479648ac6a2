"""The rollout runner shared by data generation and evaluation, and the sinks its finished episodes go to.

`runner`: plans seeded episodes and runs any registered policy in the (batched) envs; `episode`: what a finished
episode hands a sink; `records`: the JSONL episode-record sink evaluation uses (the dataset sink is `export`).
"""
