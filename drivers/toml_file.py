"""Reading a user's TOML file with one-line errors (robot configs, run configs)."""

from __future__ import annotations

import sys
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def read_toml(path: Path, what: str, error: type[Exception], example: str) -> dict:
    """The tables of TOML file `path`; `error` naming `what` the file is, the cause and the fix (`example`: a
    command or document to follow) when it cannot be read or parsed. A UTF-8 byte-order mark (Windows editors) is
    skipped."""
    try:
        return tomllib.loads(path.read_text(encoding="utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise error(f"{what} {path} is not UTF-8 text ({exc.reason} at byte {exc.start}): give a TOML file "
                    f"({example})") from None
    except OSError as exc:
        raise error(f"{what} {path} cannot be read ({exc.strerror}): check its permissions") from None
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{what} {path} is not valid TOML ({exc}): fix the syntax") from exc
