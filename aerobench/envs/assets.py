"""Optional real assets from a local folder: YCB object meshes (ReplicaCAD scenes: path check only, see below).

The embedded default is procedural and offline. With `real_assets=("ycb",)` the skill envs build the target and
distractor objects from the YCB meshes in ManiSkill's layout (`<root>/assets/mani_skill2_ycb/models/<id>/`, files
`collision.ply` and `textured.obj`) keeping the spec's masses; the folder is `assets_dir=` or `$AEROBENCH_ASSETS`
(default ManiSkill's `~/.maniskill/data`). A missing folder is a one-line error naming the path and the command that
fetches it. ReplicaCAD scenes are recognised and checked the same way, but loading them into the task settings is
not implemented in this version (the procedural layouts carry the supports and nav points the tasks need).
"""

from __future__ import annotations

import os
from pathlib import Path

ASSETS_ENV_VAR = "AEROBENCH_ASSETS"
KINDS = ("ycb", "replicacad")
YCB_FETCH = "python -m mani_skill.utils.download_asset ycb"
REPLICACAD_FETCH = "python -m mani_skill.utils.download_asset ReplicaCAD"
YCB_IDS = {
    "master_chef_can": "002_master_chef_can",
    "cracker_box": "003_cracker_box",
    "sugar_box": "004_sugar_box",
    "tomato_soup_can": "005_tomato_soup_can",
    "tuna_fish_can": "007_tuna_fish_can",
    "pudding_box": "008_pudding_box",
    "gelatin_box": "009_gelatin_box",
    "potted_meat_can": "010_potted_meat_can",
    "bowl": "024_bowl",
}


class MissingAssetError(FileNotFoundError):
    """Real assets were asked for but are not on disk."""


def assets_root(assets_dir: str | os.PathLike | None = None) -> Path:
    if assets_dir is not None:
        return Path(assets_dir).expanduser()
    if os.environ.get(ASSETS_ENV_VAR):
        return Path(os.environ[ASSETS_ENV_VAR]).expanduser()
    return Path(os.environ.get("MS_ASSET_DIR", "~/.maniskill/data")).expanduser()


def parse_real_assets(real_assets) -> tuple[str, ...]:
    kinds = tuple(real_assets.split(",")) if isinstance(real_assets, str) else tuple(real_assets or ())
    for kind in kinds:
        if kind not in KINDS:
            raise ValueError(f"unknown real asset kind {kind!r}; valid kinds: {', '.join(KINDS)}")
    return kinds


def ycb_model_dir(name: str, assets_dir=None) -> Path:
    """The YCB model folder of object `name`; raises MissingAssetError (one line) when it is not there."""
    root = assets_root(assets_dir) / "assets" / "mani_skill2_ycb" / "models"
    if name not in YCB_IDS:
        raise ValueError(f"object {name!r} has no YCB model; YCB objects: {', '.join(YCB_IDS)}")
    folder = root / YCB_IDS[name]
    if not (folder / "collision.ply").is_file() or not (folder / "textured.obj").is_file():
        raise MissingAssetError(
            f"YCB meshes not found at {folder}; fetch them with `{YCB_FETCH}` and pass assets_dir= or set {ASSETS_ENV_VAR}"
        )
    return folder


def replicacad_dir(assets_dir=None) -> Path:
    folder = assets_root(assets_dir) / "scene_datasets" / "replica_cad_dataset"
    if not folder.is_dir():
        raise MissingAssetError(
            f"ReplicaCAD not found at {folder}; fetch it with `{REPLICACAD_FETCH}` and pass assets_dir= or set {ASSETS_ENV_VAR}"
        )
    raise NotImplementedError(
        f"ReplicaCAD found at {folder}, but loading it into the task settings is not implemented yet; use the "
        "procedural scenes (the default)"
    )
