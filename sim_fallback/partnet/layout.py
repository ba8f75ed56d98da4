"""The PartNet-Mobility folder layout: a folder of objects `<id>/`, each with `mobility.urdf` (meshes under
`textured_objs/`), `semantics.txt` (`link_N JOINT_KIND PART` a line), and optionally `mobility_v2.json` (parts
and their sub-parts: where the handles are) and `meta.json` (the category)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from sim_fallback.partnet.errors import PartNetError

URDF_NAME = "mobility.urdf"
SEMANTICS_NAME = "semantics.txt"


@dataclass(frozen=True)
class Semantic:
    """One line of semantics.txt: a link's joint kind (slider, hinge, heavy, free ...) and what it is."""

    link: str
    joint_kind: str
    label: str


@dataclass(frozen=True)
class ObjectFiles:
    """What an object folder says besides its URDF: `semantics` by link name, `handle_ids` (the ids of the
    sub-parts named "handle", by link name, from mobility_v2.json; empty without that file) and `category`
    (meta.json's model_cat, "" when unknown)."""

    object_id: str
    folder: Path
    semantics: dict[str, Semantic]
    handle_ids: dict[str, frozenset[int]]
    category: str

    @property
    def urdf(self) -> Path:
        return self.folder / URDF_NAME

    @property
    def source(self) -> str:
        return f"partnet {self.object_id}"


def object_folders(assets: Path) -> list[Path]:
    """The object folders in `assets`, sorted by id (numbers numerically): its subfolders holding a
    mobility.urdf, or `assets` itself when it is one object's folder."""
    assets = Path(assets)
    if not assets.is_dir():
        raise PartNetError(f"{assets}: no such folder; fix: give the folder that holds the PartNet-Mobility "
                           f"object folders (<id>/{URDF_NAME})")
    if (assets / URDF_NAME).is_file():
        return [assets]
    found = [p for p in assets.iterdir() if (p / URDF_NAME).is_file()]
    if not found:
        raise PartNetError(f"{assets}: not in the PartNet-Mobility layout (no <id>/{URDF_NAME} in it); fix: give "
                           f"the folder that holds the object folders, e.g. partnet-mobility-dataset/")
    return sorted(found, key=lambda p: (not p.name.isdigit(), int(p.name) if p.name.isdigit() else 0, p.name))


def find_object(assets: Path, object_id: str) -> Path:
    """The folder of object `object_id` in `assets`; an error listing the ids there when it is not one."""
    folders = object_folders(assets)
    for folder in folders:
        if folder.name == str(object_id):
            return folder
    ids = [f.name for f in folders]
    shown = ", ".join(ids[:20]) + (f" ... ({len(ids)} objects)" if len(ids) > 20 else "")
    raise PartNetError(f"object {object_id} is not in {assets}: it has {shown}; fix: pick one of these ids")


def read_object_files(folder: Path) -> ObjectFiles:
    """Read an object folder's semantics.txt, mobility_v2.json and meta.json (one-line errors when unusable)."""
    folder = Path(folder)
    name = f"partnet {folder.name}"
    if not (folder / URDF_NAME).is_file():
        raise PartNetError(f"{name} ({folder}): no {URDF_NAME}; fix: give a PartNet-Mobility object folder")
    semantics_path = folder / SEMANTICS_NAME
    if not semantics_path.is_file():
        raise PartNetError(f"{name}: no {SEMANTICS_NAME}, so its drawers and doors are unknown; fix: restore the "
                           f"file from the dataset")
    return ObjectFiles(folder.name, folder, _read_semantics(semantics_path, name), _read_handle_ids(folder, name),
                       _read_category(folder))


def _read_semantics(path: Path, name: str) -> dict[str, Semantic]:
    semantics = {}
    for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
        words = line.split()
        if not words:
            continue
        if len(words) != 3:
            raise PartNetError(f"{name}: {SEMANTICS_NAME} line {number} {line.strip()!r} is not 'LINK JOINT_KIND "
                               f"PART'; fix: restore the file from the dataset")
        semantics[words[0]] = Semantic(*words)
    return semantics


def _read_handle_ids(folder: Path, name: str) -> dict[str, frozenset[int]]:
    path = folder / "mobility_v2.json"
    if not path.is_file():
        return {}
    try:
        parts = json.loads(path.read_text())
        return {f"link_{part['id']}": frozenset(int(sub["id"]) for sub in part.get("parts", ())
                                                if sub.get("name") == "handle")
                for part in parts}
    except (ValueError, KeyError, TypeError) as exc:
        raise PartNetError(f"{name}: mobility_v2.json is unreadable ({exc}); fix: restore it from the dataset, "
                           f"or remove it (handles are then unknown)") from exc


def _read_category(folder: Path) -> str:
    try:
        return str(json.loads((folder / "meta.json").read_text()).get("model_cat", ""))
    except (OSError, ValueError, AttributeError):
        return ""
