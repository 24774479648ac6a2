"""Procedural scenes, built from primitives, seeded and offline.

A generator turns a numpy `Generator` into a `layout.SceneLayout` (pure data); `build.build_layouts` turns layouts
into SAPIEN actors and fixture articulations. `SCENE_GENERATORS` maps the task settings' scene names to generators:
`apartment` (TidyHouse), `kitchen` (PrepareGroceries), `street` (PackageDelivery), `home` (LongHorizonRearrangement).
`room` is the flight-test room of `AeroFly-v1`; `furniture` holds the pieces and the placement geometry the generators
share; `articulated` the fridge and the counter drawer.
"""

from __future__ import annotations

from collections.abc import Callable
from types import MappingProxyType

import numpy as np

from .apartment import generate_apartment
from .home import generate_home
from .kitchen import generate_kitchen
from .layout import SceneLayout
from .street import generate_street

SCENE_GENERATORS: MappingProxyType[str, Callable[[np.random.Generator], SceneLayout]] = MappingProxyType(
    {"apartment": generate_apartment, "kitchen": generate_kitchen, "street": generate_street, "home": generate_home}
)


def generate_layout(name: str, rng: np.random.Generator) -> SceneLayout:
    """The layout of scene `name` drawn from `rng` (same seed, same layout)."""
    try:
        generator = SCENE_GENERATORS[name]
    except KeyError:
        raise ValueError(f"unknown scene {name!r}; valid scenes: apartment, kitchen, street, home") from None
    return generator(rng)


__all__ = ["SCENE_GENERATORS", "SceneLayout", "generate_layout"]
