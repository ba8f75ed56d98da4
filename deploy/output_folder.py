"""Nothing replaced without asking: a command that writes a recording or a run folder refuses one that exists
unless the user passed `--overwrite`, and an overwrite removes every file of the old one first (a shorter new
recording must not keep the old frames or the old truth.json).

Only a folder this project wrote is ever removed: a frames recording (meta.json) or a run folder (steps.json or
frames/); anything else is refused even with --overwrite.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from deploy.errors import RecordingError

MARKERS = ("meta.json", "steps.json", "frames")  # what a frames recording or a run folder holds


def prepare_output(path: Path, overwrite: bool, what: str, option: str = "--out") -> None:
    """Make `path` ready to be written as a new `what` ("recording", "run folder"): nothing to do if it does not
    exist or is an empty folder; removed if it is one of ours and `overwrite`; RecordingError naming the fix
    otherwise."""
    path = Path(path)
    if not path.exists() or (path.is_dir() and not any(path.iterdir())):
        return
    if not path.is_dir():
        raise RecordingError(f"{option} {path} is a file, not a {what}: choose another path")
    if not any((path / marker).exists() for marker in MARKERS):
        raise RecordingError(f"{option} {path} is a folder that holds no recording or run folder: refusing to "
                             "write into it; choose a new or empty folder")
    if not overwrite:
        raise RecordingError(f"{option} {path}: a {what} is already there: pass --overwrite to replace it (its files "
                             f"are removed first), or choose another {option}")
    shutil.rmtree(path)
