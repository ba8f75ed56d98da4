"""What the `deploy` commands print: JSON on stdout, rich tables, and progress (bars on a terminal, lines
elsewhere) and log lines on stderr."""

from __future__ import annotations

import json
import logging
import math
import sys
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich import box
from rich.console import Console
from rich.table import Table

if TYPE_CHECKING:
    from rich.progress import Progress, ProgressColumn, TaskID

console = Console()
err_console = Console(stderr=True)


OUR_PACKAGES = ("deploy", "drivers", "calibration", "sim_fallback")
STEP_LOGGER = "deploy.control.steps"  # deploy.control.view's per-step lines, shown without --verbose too


class _StderrHandler(logging.StreamHandler):
    """One plain line per record on the current sys.stderr (never wrapped, whatever the width)."""

    def emit(self, record: logging.LogRecord) -> None:
        self.stream = sys.stderr  # not setStream: it would flush the old stream, which may be closed by now
        super().emit(record)


def _log_handler(verbose: bool) -> logging.Handler:
    """Without `verbose` (the step lines only): plain lines. With it: rich's columns (time, level, where) on a
    terminal; plain lines with time, level and logger elsewhere (a file or a pipe: one line per record)."""
    if verbose and err_console.is_terminal:
        from rich.logging import RichHandler

        handler: logging.Handler = RichHandler(console=err_console, show_path=True, markup=False,
                                               rich_tracebacks=False)
        handler.setFormatter(logging.Formatter("%(message)s"))
    else:
        handler = _StderrHandler()
        handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)-7s %(name)s: %(message)s" if verbose
                                               else "%(message)s"))
    handler.axisloop = True  # type: ignore[attr-defined]
    return handler


def configure_logging(verbose: bool) -> None:
    """Log records to stderr: the episode's step lines always (one line each); with `verbose` every INFO record
    and our packages' DEBUG records too (run config, devices, calibration, detections, grasp, estimates).
    Without `verbose` nothing else changes (other records go where Python's logging sends them by default)."""
    root, steps = logging.getLogger(), logging.getLogger(STEP_LOGGER)
    for logger in (root, steps):
        for handler in [h for h in logger.handlers if getattr(h, "axisloop", False)]:
            logger.removeHandler(handler)
    (root if verbose else steps).addHandler(_log_handler(verbose))
    root.setLevel(logging.INFO if verbose else logging.WARNING)
    for name in OUR_PACKAGES:
        logging.getLogger(name).setLevel(logging.DEBUG if verbose else logging.NOTSET)
    steps.setLevel(logging.INFO)


def print_json(data: dict) -> None:
    """`data` as one indented JSON object on stdout (the `--json` output of every command)."""
    sys.stdout.write(json.dumps(data, indent=2) + "\n")


def print_rows(title: str, rows: dict, digits: int | None = 3) -> None:
    """`rows` as a two-column table: floats with `digits` decimals but at least two significant digits (0.0012,
    not 0.001; None: as they are), None as "-", a dict as "key value, key value" ("none" when empty), a list as
    "[a, b]"."""
    table = Table(title=title, show_header=False)
    table.add_column(no_wrap=True)  # keys whole; values wrap (never "…") to fit the terminal
    table.add_column(overflow="fold")
    for key, value in rows.items():
        table.add_row(key, _cell(value, digits))
    console.print(_compact_if_wide(table))


def _cell(value: Any, digits: int | None) -> str:
    """One value of `print_rows` as text (dicts and lists element by element)."""
    if value is None:
        return "-"
    if isinstance(value, dict):
        return ", ".join(f"{key} {_cell(item, digits)}" for key, item in value.items()) or "none"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_cell(item, digits) for item in value) + "]"
    if isinstance(value, float) and digits is not None:
        if value == 0 or not math.isfinite(value):
            return f"{value:.{digits}f}"
        if abs(value) < 1e-6:
            return f"{value:.2g}"
        return f"{value:.{max(digits, 1 - math.floor(math.log10(abs(value))))}f}"  # two significant digits or more
    return str(value)


def print_table(title: str, columns: Iterable[str], rows: Iterable[Sequence[str]], **column: Any) -> None:
    """A table with a header row. Nothing is cut to "…" on a narrow terminal: the first column (names) never
    wraps, the others wrap (fold) to fit. `column` holds rich column options that override these for every
    column."""
    table = Table(title=title)
    for i, name in enumerate(columns):
        table.add_column(name, **({"no_wrap": True} if i == 0 else {"overflow": "fold"}) | column)
    for row in rows:
        table.add_row(*row)
    console.print(_compact_if_wide(table))


def _compact_if_wide(table: Table) -> Table:
    """`table` without its vertical rules and outer padding when it would not fit the terminal's width otherwise
    (one space between columns, instead of " │ ")."""
    if console.measure(table, options=console.options.update(width=10_000)).maximum > console.width:
        table.box, table.show_edge, table.padding = box.SIMPLE_HEAD, False, (0, 0)
    return table


def fmt(value: float | None, scale: float = 1.0, digits: int = 2) -> str:
    """`value * scale` with `digits` decimals, "-" for None."""
    return "-" if value is None else f"{value * scale:.{digits}f}"


class Bar:
    """One task of a transient progress display; its methods fit the `progress=` callbacks of the library."""

    def __init__(self, progress: Progress, job: TaskID, label: str = "") -> None:
        self._progress, self._job, self._label = progress, job, label

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
        """Show what is running now (after the bar's label)."""
        self._progress.update(self._job, description=f"{self._label}: {what}" if self._label else what)


class LineBar:
    """`Bar` for a stderr that is not a terminal (a log file, a pipe, CI), where a live bar shows nothing:
    plain lines `LABEL: 40/133` (or `LABEL: 40` without a total) at most every `every_s` seconds, a line per
    new description (phase), and the last count at the end when a count line was printed."""

    def __init__(self, label: str, total: float | None = None, every_s: float = 2.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.label, self.total, self.every_s, self.clock = label, total, every_s, clock
        self.done: float = 0
        self._printed_at = clock()
        self._shown: float | None = None

    def _line(self, text: str) -> None:
        sys.stderr.write(f"{text}\n")
        sys.stderr.flush()

    def _count(self, force: bool = False) -> None:
        now = self.clock()
        if (force or now - self._printed_at >= self.every_s) and self.done != self._shown:
            total = "" if self.total is None else f"/{self.total:g}"
            self._line(f"{self.label}: {self.done:g}{total}")
            self._printed_at, self._shown = now, self.done

    def counts(self, done: float, total: float | None) -> None:
        self.done, self.total = done, total
        self._count()

    def completed(self, done: float) -> None:
        self.done = done
        self._count()

    def advance(self, _item: object = None) -> None:
        self.done += 1
        self._count()

    def describe(self, what: str) -> None:
        self._line(f"{self.label}: {what}")
        self._printed_at = self.clock()

    def finish(self) -> None:
        if self._shown is not None:
            self._count(force=True)


@contextmanager
def progress_bar(label: str, total: float | None = None, *columns: str | ProgressColumn) -> Iterator[Bar | LineBar]:
    """Progress on stderr: on a terminal a bar with counts that disappears when done (`columns` replace the
    default ones), elsewhere `LineBar`'s plain lines."""
    if not err_console.is_terminal:
        bar = LineBar(label, total)
        yield bar
        bar.finish()
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    columns = columns or (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with Progress(*columns, console=err_console, transient=True) as progress:
        yield Bar(progress, progress.add_task(label, total=total), label)


def view_file(recording: Path, rrd: Path | None, what: str, overwrite: bool | None = None) -> Path:
    """Where `--view` on a recording saves its rerun file: `rrd` when given, else runs/NAME-WHAT.rrd (NAME: the
    recording folder's, a run folder's for its RUN/frames; NAME-WHAT-2.rrd, -3, ... when taken), never inside the
    recording (it may be read-only, or a shared data set). An existing `rrd` is replaced only with `overwrite`
    (None: the command has no --overwrite); RecordingError otherwise."""
    from deploy.errors import RecordingError
    from deploy.output_folder import check_apart, kind_of

    if rrd is None:
        source = Path(recording).resolve()
        name = source.parent.name if source.name == "frames" and kind_of(source.parent) == "run folder" \
            else source.name
        path, k = Path("runs") / f"{name}-{what}.rrd", 1
        while path.exists():
            k += 1
            path = path.with_name(f"{name}-{what}-{k}.rrd")
        return path
    check_apart(rrd, [recording], "--rrd")
    if rrd.is_dir():
        raise RecordingError(f"--rrd {rrd} is a folder: give a file path, e.g. {rrd / (what + '.rrd')}")
    if rrd.exists() and not overwrite:
        fix = "choose another --rrd, or delete the file first" if overwrite is None else \
            "pass --overwrite to replace it, or choose another --rrd"
        raise RecordingError(f"--rrd {rrd} already exists: refusing to replace it; {fix}")
    return rrd
