"""What the `deploy` commands print: JSON on stdout, rich tables, and progress bars on stderr."""

from __future__ import annotations

import json
import logging
import sys
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.table import Table

if TYPE_CHECKING:
    from rich.progress import Progress, ProgressColumn, TaskID

console = Console()
err_console = Console(stderr=True)


OUR_PACKAGES = ("deploy", "drivers", "calibration", "sim_fallback")
STEP_LOGGER = "deploy.control.steps"  # deploy.control.viewer's per-step lines, shown without --verbose too


def configure_logging(verbose: bool) -> None:
    """Log records to stderr through rich: the episode's step lines always; with `verbose` every INFO record
    and our packages' DEBUG records too. Without `verbose` nothing else changes (other records go where
    Python's logging sends them by default)."""
    from rich.logging import RichHandler

    root, steps = logging.getLogger(), logging.getLogger(STEP_LOGGER)
    for logger in (root, steps):
        for handler in [h for h in logger.handlers if getattr(h, "axisloop", False)]:
            logger.removeHandler(handler)
    handler = RichHandler(console=err_console, show_time=verbose, show_level=verbose, show_path=verbose,
                          markup=False, rich_tracebacks=False)
    handler.axisloop = True  # type: ignore[attr-defined]
    handler.setFormatter(logging.Formatter("%(message)s"))
    (root if verbose else steps).addHandler(handler)
    root.setLevel(logging.INFO if verbose else logging.WARNING)
    for name in OUR_PACKAGES:
        logging.getLogger(name).setLevel(logging.DEBUG if verbose else logging.NOTSET)
    steps.setLevel(logging.INFO)


def print_json(data: dict) -> None:
    """`data` as one indented JSON object on stdout (the `--json` output of every command)."""
    sys.stdout.write(json.dumps(data, indent=2) + "\n")


def print_rows(title: str, rows: dict, digits: int | None = 3) -> None:
    """`rows` as a two-column table: floats with `digits` decimals (None: as they are), None as "-"."""
    table = Table(title=title, show_header=False)
    for key, value in rows.items():
        text = "-" if value is None else f"{value:.{digits}f}" if isinstance(value, float) and digits is not None \
            else str(value)
        table.add_row(key, text)
    console.print(table)


def print_table(title: str, columns: Iterable[str], rows: Iterable[Sequence[str]], **column: Any) -> None:
    """A table with a header row; `column` holds rich column options (e.g. overflow="fold") for every column."""
    table = Table(title=title)
    for name in columns:
        table.add_column(name, **column)
    for row in rows:
        table.add_row(*row)
    console.print(table)


def fmt(value: float | None, scale: float = 1.0, digits: int = 2) -> str:
    """`value * scale` with `digits` decimals, "-" for None."""
    return "-" if value is None else f"{value * scale:.{digits}f}"


class Bar:
    """One task of a transient progress display; its methods fit the `progress=` callbacks of the library."""

    def __init__(self, progress: Progress, job: TaskID) -> None:
        self._progress, self._job = progress, job

    def counts(self, done: float, total: float | None) -> None:
        """`done` of `total` steps (a total learned as the work runs)."""
        self._progress.update(self._job, completed=done, total=total)

    def completed(self, done: float) -> None:
        """`done` of the total given when the bar was made."""
        self._progress.update(self._job, completed=done)

    def advance(self, _item: object = None) -> None:
        """One more step (the finished item itself is not shown)."""
        self._progress.advance(self._job)

    def describe(self, what: str) -> None:
        """Show what is running now."""
        self._progress.update(self._job, description=what)


@contextmanager
def progress_bar(label: str, total: float | None = None, *columns: str | ProgressColumn) -> Iterator[Bar]:
    """A progress bar on stderr that disappears when done; `columns` replace rich's default ones."""
    from rich.progress import Progress

    with Progress(*columns, console=err_console, transient=True) as progress:
        yield Bar(progress, progress.add_task(label, total=total))
