"""Named evaluation conditions: what breaks aerial policies, applied in the env, recorded in the results.

registry.py   the named, versioned conditions as data (`CONDITIONS`, `resolve_condition`, `describe_conditions`)
constants.py  their physical constants, each with its source
wind.py       constant wind + Dryden turbulence (MIL-F-8785C), rotor and parasitic drag
proximity.py  ground effect (Cheeseman & Bennett), ceiling effect, near-wall suction, from the scene's boxes
motors.py     first-order rotor lag, thrust headroom
sensors.py    noise and delay on the state estimate a policy reads
visual.py     what the cameras see: lighting, surface colours (at the build), camera noise, motion blur (per frame)
physics.py    the conditioned physics step (eager): the controller's laws, then the condition's models
runtime.py    an env's conditions while it runs: per-env seeded streams, per-episode draws, per-step state, frames

An env takes `condition=("wind_gusty_3ms", ...)` (default: none, today's physics bit for bit: the fused step and the
observations and camera frames are untouched); `aerobench conditions` lists them.
"""

from .registry import CONDITIONS, Condition, ConditionSet, describe_conditions, get_condition, resolve_condition

__all__ = ["CONDITIONS", "Condition", "ConditionSet", "describe_conditions", "get_condition", "resolve_condition"]
