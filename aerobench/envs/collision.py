"""Self-collision filtering per articulation.

SAPIEN/PhysX skips a contact when two shapes share a bit in collision group 2 (and group 3 matches). ManiSkill's
`disable_self_collisions` sets bit 29 on every articulation that asks for it, which would also stop the drone from
touching the fridge or the drawer. Each articulation therefore gets a bit of its own here.
"""

from __future__ import annotations

from mani_skill.utils.structs import Articulation

SELF_COLLISION_BITS = {"drone": 28, "fridge": 27, "drawer": 26}


def ignore_self_collisions(articulation: Articulation, owner: str) -> None:
    """Links of `articulation` no longer collide with each other, but still with everything else."""
    bit = SELF_COLLISION_BITS[owner]
    for link in articulation.links:
        link.set_collision_group_bit(group=2, bit_idx=bit, bit=1)
