"""Task settings and skill chains as data: which scene, objects, supports, fixtures and instruction per setting.

Spec "Benchmark Design": TidyHouse and PrepareGroceries give object-specific Pick and Place; PackageDelivery is
Pick (from a vehicle) -> Nav (to a room entrance) -> Place (on the cabinet by the door); LongHorizonRearrangement
chains Open and Close of the fridge or the drawer around Pick -> Nav -> Place. Nothing here is code per setting.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from .objects import ALL_OBJECTS, OBJECTS

SKILLS = ("pick", "place", "nav", "open", "close")
# Spec platform table, "Target subtasks": the gripper platform picks and places; the arm platform opens and closes
# (its gripper also picks and places, which the long-horizon chains need in one flight).
DEFAULT_PLATFORM = MappingProxyType({"pick": "gripper", "place": "gripper", "nav": "gripper", "open": "arm", "close": "arm"})
FIXTURE_PHRASES = MappingProxyType({"fridge": "the refrigerator door", "drawer": "the kitchen drawer"})


@dataclass(frozen=True)
class Subtask:
    """One stage of a chain. `where` names support kinds (pick/place), a fixture (open/close) or a nav point."""

    skill: str
    where: tuple[str, ...] = ()


@dataclass(frozen=True)
class TaskSetting:
    name: str
    scene: str  # a scene generator name (scenes.SCENE_GENERATORS)
    objects: tuple[str, ...]
    skills: tuple[str, ...]
    pick_supports: tuple[str, ...]  # support kinds objects start on
    place_supports: tuple[str, ...]  # support kinds placement goals lie on
    fixtures: tuple[str, ...] = ()
    chains: Mapping[str, tuple[Subtask, ...]] = MappingProxyType({})
    chain_platform: str = "gripper"
    description: str = ""

    def check_object(self, name: str) -> None:
        if name not in ALL_OBJECTS:
            raise ValueError(f"unknown object {name!r}; valid objects: {', '.join(ALL_OBJECTS)}")
        if name not in self.objects:
            raise ValueError(f"object {name!r} is not part of {self.name}; its objects are: {', '.join(self.objects)}")

    def check_skill(self, skill: str) -> None:
        if skill not in self.skills:
            raise ValueError(f"{self.name} has no {skill} skill; its skills are: {', '.join(self.skills)}")

    def chain(self, name: str | None) -> tuple[str, tuple[Subtask, ...]]:
        if not self.chains:
            raise ValueError(f"{self.name} has no sequential chains")
        name = name or next(iter(self.chains))
        if name not in self.chains:
            raise ValueError(f"unknown chain {name!r} for {self.name}; valid chains: {', '.join(self.chains)}")
        return name, self.chains[name]


_HOUSEHOLD = ("table", "counter", "shelf", "cabinet")
_NINE = tuple(OBJECTS)  # the spec's nine classes
_GROCERIES = tuple(o for o in OBJECTS if o != "cracker_box")  # the spec's PrepareGroceries table: 8 objects

SETTINGS: Mapping[str, TaskSetting] = MappingProxyType(
    {
        s.name: s
        for s in (
            TaskSetting(
                name="TidyHouse",
                scene="apartment",
                objects=_NINE,
                skills=("pick", "place", "nav"),
                pick_supports=_HOUSEHOLD,
                place_supports=_HOUSEHOLD,
                chains=MappingProxyType(
                    {"pick_nav_place": (Subtask("pick"), Subtask("nav"), Subtask("place"))}
                ),
                description="household rearrangement in a procedural apartment",
            ),
            TaskSetting(
                name="PrepareGroceries",
                scene="kitchen",
                objects=_GROCERIES,
                skills=("pick", "place", "nav", "open", "close"),
                pick_supports=("counter", "table"),
                place_supports=("counter", "table"),
                fixtures=("fridge", "drawer"),
                chains=MappingProxyType(
                    {"pick_nav_place": (Subtask("pick"), Subtask("nav"), Subtask("place"))}
                ),
                description="kitchen rearrangement with a refrigerator and a counter drawer",
            ),
            TaskSetting(
                name="PackageDelivery",
                scene="street",
                objects=("package",),
                skills=("pick", "place", "nav"),
                pick_supports=("vehicle",),
                place_supports=("cabinet",),
                chains=MappingProxyType(
                    {
                        "deliver": (
                            Subtask("pick", ("vehicle",)),
                            Subtask("nav", ("the building entrance",)),
                            Subtask("place", ("cabinet",)),
                        )
                    }
                ),
                description="outdoor delivery: from a vehicle, through a building entrance, onto a cabinet",
            ),
            TaskSetting(
                name="LongHorizonRearrangement",
                scene="home",
                objects=_NINE,
                skills=("pick", "place", "nav", "open", "close"),
                pick_supports=_HOUSEHOLD,
                place_supports=_HOUSEHOLD,
                fixtures=("fridge", "drawer"),
                chains=MappingProxyType(
                    {
                        "open_pick_nav_place": (
                            Subtask("open", ("fridge",)),
                            Subtask("pick", ("fridge_shelf",)),
                            Subtask("nav"),
                            Subtask("place", ("table", "counter")),
                        ),
                        "open_pick_nav_place_close": (
                            Subtask("open", ("drawer",)),
                            Subtask("pick", ("table", "counter")),
                            Subtask("nav"),
                            Subtask("place", ("drawer",)),
                            Subtask("close", ("drawer",)),
                        ),
                    }
                ),
                chain_platform="arm",
                description="apartment plus kitchen: open, pick, navigate, place, close in one flight",
            ),
        )
    }
)


def get_setting(name: str) -> TaskSetting:
    try:
        return SETTINGS[name]
    except KeyError:
        raise ValueError(f"unknown setting {name!r}; valid settings: {', '.join(SETTINGS)}") from None


def snake_name(setting: str) -> str:
    """`LongHorizonRearrangement` -> `long_horizon_rearrangement`: how file names (configs/<policy>_<name>.json) say it."""
    return re.sub(r"(?<!^)(?=[A-Z])", "_", setting).lower()


def object_phrase(name: str) -> str:
    return name.replace("_", " ")


def instruction(skill: str, *, obj: str = "", where: str = "", target: str = "") -> str:
    """The language instruction of one skill, from templates ("pick up the tomato soup can from the kitchen counter",
    "place the bowl on the marked spot of the dining table")."""
    if skill == "pick":
        return f"pick up the {object_phrase(obj)} from {where}"
    if skill == "place":  # the goal point is marked in the scene (envs.skills.markers): the instruction says so
        return f"place the {object_phrase(obj)} on the marked spot of {where}"
    if skill == "nav":
        return f"fly to {target}"
    if skill in ("open", "close"):
        return f"{skill} {FIXTURE_PHRASES[target]}"
    raise ValueError(f"unknown skill {skill!r}; valid skills: {', '.join(SKILLS)}")


def chain_instruction(parts: list[str]) -> str:
    return ", then ".join(parts)
