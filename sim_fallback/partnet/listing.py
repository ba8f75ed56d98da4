"""What a folder of PartNet-Mobility objects holds: each object's parts (kind, link, joint, range in real units),
or one line saying why it cannot be used."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim_fallback.furniture import Furniture
from sim_fallback.partnet.errors import PartNetError
from sim_fallback.partnet.layout import object_folders, read_object_files
from sim_fallback.partnet.loader import ScaleRule, load_partnet
from sim_fallback.partnet.model import PartNetModel


@dataclass(frozen=True)
class ObjectEntry:
    """One object of a folder: its `furniture` when usable, else `problem` (one line: what, why, the fix);
    `ignored` says, a line each, which moving links are not parts and why."""

    object_id: str
    category: str
    furniture: Furniture | None
    problem: str | None
    ignored: tuple[str, ...] = ()

    def describe(self) -> dict:
        """The entry as JSON-ready values: id, category, scale, size, parts (name, kind, link, joint, range with
        its unit, handle style), the links that are not parts, and the problem."""
        out = {"id": self.object_id, "category": self.category, "problem": self.problem, "ignored": list(self.ignored)}
        f = self.furniture
        if f is not None:
            out |= {"scale": round(f.scale, 4), "size_m": [round(v, 3) for v in f.size_m],
                    "parts": [{"name": p.name, "kind": p.kind, "link": p.link, "joint": p.joint,
                               "range": [0.0, round(p.upper if p.kind == "drawer" else float(np.degrees(p.upper)), 3)],
                               "unit": "m" if p.kind == "drawer" else "deg",
                               "handle": p.handle.style if p.handle is not None else None} for p in f.parts]}
        return out


def list_objects(assets: Path, scale: ScaleRule = "real") -> list[ObjectEntry]:
    """Every object in `assets` (a folder of object folders, or one object's folder), sorted by id, loaded at
    `scale`; an object that cannot be used carries its one-line problem instead."""
    return [_entry(folder, scale) for folder in object_folders(assets)]


def usable(entries: list[ObjectEntry]) -> list[ObjectEntry]:
    """The entries that loaded (the objects a benchmark cycles through)."""
    return [e for e in entries if e.furniture is not None]


def _entry(folder: Path, scale: ScaleRule) -> ObjectEntry:
    category, ignored = "", ()
    try:
        category = read_object_files(folder).category
        ignored = tuple(PartNetModel(folder).ignored_links())
        return ObjectEntry(folder.name, category, load_partnet(folder, scale=scale), None, ignored)
    except PartNetError as exc:
        return ObjectEntry(folder.name, category, None, str(exc), ignored)
