"""The skill envs (one module per skill over the shared `base.AeroSkillEnv`) and the sequential env.

Registered ids: AeroPick-v1, AeroPlace-v1, AeroNav-v1, AeroOpen-v1, AeroClose-v1, AeroSequential-v1. Each skill's
completion check lives in its evaluator (`pick.PickEvaluator`, ...), so a chain reuses them unchanged.
"""

from . import articulation, nav, pick, place, sequential  # noqa: F401  (registration side effects)
