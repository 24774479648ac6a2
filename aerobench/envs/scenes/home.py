"""The LongHorizonRearrangement home: the apartment with the kitchen (fridge and counter drawer) in place of the study.

The kitchen sits in the apartment's top row and is reached through a doorway from the room below it, so a long-horizon
chain can open the fridge, fly the object through the home and place it in another room (or the reverse).
"""

from __future__ import annotations

import numpy as np

from .apartment import generate_rooms
from .layout import SceneLayout


def generate_home(rng: np.random.Generator) -> SceneLayout:
    """Living room, dining room, bedroom and kitchen, with the fridge and the drawer fixtures."""
    return generate_rooms(rng, with_kitchen=True)
