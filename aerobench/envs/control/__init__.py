"""The flight controller as pure batched torch: state and commands in, rotor thrusts and a world wrench out.

Nothing here imports SAPIEN or ManiSkill, so every law is testable on its own. Tensors are `(num_envs, ...)`.
- `so3`: rotation helpers (Euler ZYX, hat/vee, quaternions wxyz).
- `virtual_joints`: the six virtual joints of the airframe: joint state -> rigid-body state, and Q = J^T W.
- `flight`: the cascaded velocity-attitude controller and rotor allocation (spec Sec. 3.2).
- `payload`: the payload-aware switches (spec appendix "Payload-Aware Flight Control").
- `arm`: arm-platform extras: arm weight-moment feedforward, servo torques, contact mode.
"""
