"""Nothing replaced without asking: a command that writes a recording or a run folder refuses one that exists
unless the user passed `--overwrite`, and an overwrite removes every file of the old one (a shorter new recording
must not keep the old frames or the old truth.json), but only once the new one is under way: a command refused
before it wrote anything puts the old one back.

Only a folder this project wrote is ever removed: a frames recording (meta.json) or a run folder (steps.json or
frames/) holding nothing but what this project writes there; anything else is refused even with --overwrite. An
output is never the recording it reads, nor inside it, nor around it.

A command killed outright (kill -9, power loss) leaves its hidden work behind: the old output an overwrite set
aside (`.NAME.replaced-XXXXXXXX`, beside it) and a track's half-written masks (`.mask-XXXXXXXX.partial`, inside the
recording; XXXXXXXX: 8 hex digits). These exact names count as this project's: the masks go with the recording
they lie in, and an output's set-aside old ones of its kind go when it is next overwritten. Any other name stays a
stranger.
"""

from __future__ import annotations

import glob
import re
import shutil
import uuid
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from fnmatch import fnmatch
from pathlib import Path

from deploy.errors import RecordingError

Layout = str | dict[str | re.Pattern[str], "Layout | None"]
"""name (or a pattern the whole name matches) -> None (a file) or a layout (a folder); a str: files matching it"""
PNGS = "*.png"
MASKS_PARTIAL = re.compile(r"\.mask-[0-9a-f]{8}\.partial")  # `deploy track`'s masks being written (perception)
RECORDING: Layout = {"meta.json": None, "frames.jsonl": None, "truth.json": None, "color": PNGS, "depth": PNGS,
                     "mask": PNGS, "overlay.png": None, "track.json": None, "track.rrd": None, "recording.rrd": None,
                     MASKS_PARTIAL: PNGS}
RUN_FOLDER: Layout = {"frames": RECORDING, "config.json": None, "steps.json": None, "report.png": None,
                      "episode.rrd": None}
OURS = {"recording": (RECORDING, ("meta.json",)), "run folder": (RUN_FOLDER, ("steps.json", "frames"))}
"""what a command writes -> its layout and the names that mark it"""


def stranger(path: Path, layout: Layout) -> Path | None:
    """The first file or folder under the folder `path` that `layout` does not hold (None: nothing else is there;
    a symbolic link always counts as a stranger)."""
    for entry in sorted(path.iterdir()):
        ours, inner = (fnmatch(entry.name, layout), None) if isinstance(layout, str) else _lookup(layout, entry.name)
        if not ours or entry.is_symlink() or entry.is_dir() != (inner is not None):
            return entry
        if inner is not None and (found := stranger(entry, inner)) is not None:
            return found
    return None


def _lookup(layout: dict, name: str) -> tuple[bool, Layout | None]:
    """Whether `layout` holds `name` (by name, or by a pattern the whole name matches), and what it holds there."""
    if name in layout:
        return True, layout[name]
    for key, inner in layout.items():
        if isinstance(key, re.Pattern) and key.fullmatch(name):
            return True, inner
    return False, None


def set_aside(path: Path, what: str) -> list[Path]:
    """The old outputs `new_output` set aside beside `path` and never removed (it was killed): folders named
    exactly `.NAME.replaced-XXXXXXXX` that hold a `what` ("recording", "run folder") and nothing else."""
    name = re.compile(re.escape(f".{path.name}.replaced-") + "[0-9a-f]{8}")
    found = [p for p in sorted(path.parent.glob(f".{glob.escape(path.name)}.replaced-*"))
             if name.fullmatch(p.name) and p.is_dir() and not p.is_symlink()]
    return [p for p in found if kind_of(p) == what and stranger(p, OURS[what][0]) is None]


def kind_of(path: Path) -> str | None:
    """What of ours the folder `path` is marked as ("recording", "run folder"; None: neither)."""
    return next((kind for kind, (_, markers) in OURS.items() if any((path / m).exists() for m in markers)), None)


def replay_input(camera: str) -> list[Path]:
    """The recording the camera spec `camera` reads (`replay:PATH`), if any."""
    name, _, argument = str(camera).partition(":")
    return [Path(argument)] if name == "replay" and argument else []


def check_apart(out: Path, inputs: Iterable[Path], option: str = "--out") -> None:
    """RecordingError when `out` is one of the recordings `inputs` the command reads, lies inside one or holds
    one: writing there would change or remove what is read."""
    target = Path(out).resolve()
    for source in inputs:
        read = Path(source).resolve()
        how = ("is" if target == read else "lies inside" if read in target.parents else
               "holds" if target in read.parents else None)
        if how is not None:
            raise RecordingError(f"{option} {out} {how} the recording {source} that this command reads: writing "
                                 f"there would change or remove it; give {option} a path outside it")


def check_output(path: Path, overwrite: bool, what: str, option: str = "--out",
                 inputs: Iterable[Path] = ()) -> bool:
    """Check that `path` may be written as a new `what` ("recording", "run folder"): apart from `inputs`, and new,
    an empty folder, or one of ours with `overwrite`; True when an old one is there to replace. RecordingError
    naming the fix otherwise."""
    path = Path(path)
    check_apart(path, inputs, option)
    if not path.exists() or (path.is_dir() and not any(path.iterdir())):
        return False
    if not path.is_dir():
        raise RecordingError(f"{option} {path} is a file, not a {what}: choose another path")
    kind = kind_of(path)
    if kind is None:
        raise RecordingError(f"{option} {path} is a folder that holds no recording or run folder: refusing to "
                             "write into it; choose a new or empty folder")
    if kind != what:
        raise RecordingError(f"{option} {path} holds a {kind}, not a {what}: refusing to replace it, even with "
                             f"--overwrite; choose another {option}")
    found = stranger(path, OURS[kind][0])
    if found is not None:
        name = found.relative_to(path)
        raise RecordingError(f"{option} {path} holds {name}, which deploy never writes there: refusing to remove the "
                             f"folder, even with --overwrite; move {name} out, or choose another {option}")
    if not overwrite:
        raise RecordingError(f"{option} {path}: a {what} is already there: pass --overwrite to replace it (no file of "
                             f"the old one is kept), or choose another {option}")
    return True


@contextmanager
def new_output(path: Path, overwrite: bool, what: str, option: str = "--out", inputs: Iterable[Path] = (),
               claimed: bool = False) -> Iterator[Path]:
    """Write a new `what` at `path` inside the block, checked by `check_output`. An old one replaced is moved
    aside to a hidden sibling and removed once the block ends having written into `path` (or without error), with
    any older ones an earlier, killed overwrite left there (`set_aside`); a block that fails before writing
    anything puts it back, and removes the empty folder it left (`claimed`: the caller made `path` for this
    block)."""
    path = Path(path)
    try:
        replacing = check_output(path, overwrite, what, option, inputs)
    except RecordingError:
        if claimed:
            path.rmdir()
        raise
    leftovers = set_aside(path, what) if replacing else []  # only along with an old one of the same kind
    old = path.with_name(f".{path.name}.replaced-{uuid.uuid4().hex[:8]}") if replacing else None
    if old is not None:
        path.rename(old)
    made = claimed or not path.exists()
    done = False
    try:
        yield path
        done = True
    finally:
        if done or (path.is_dir() and any(path.iterdir())):
            for gone in ([old] if old is not None else []) + leftovers:
                shutil.rmtree(gone)
        else:
            if made and path.is_dir():
                path.rmdir()
            if old is not None:
                old.rename(path)
