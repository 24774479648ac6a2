"""The benchmark: batched evaluation of any registered policy, statistics, trajectory metrics and leaderboards.

`evaluate` runs the shared rollout runner into a JSONL record sink and writes a versioned results JSON;
`stats` holds the SE / Wilson / paired tests and Holm's correction; `results` turns records into per skill x object
cells; `compare` pairs two evals episode by episode and `plan` sizes one; `metrics` the spec's trajectory-diversity
and time-to-success measures; `leaderboard` renders results files as Markdown and LaTeX (`row_facts`: a row's group
and recipe) and `leaderboard_html` as one page; `held_out` counts the evaluation starts a learned policy's training
data already had.
"""
