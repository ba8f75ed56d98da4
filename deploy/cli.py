"""The `deploy` command line: the command groups of deploy/commands/ assembled into one app, and `main()`.

Each command is a thin typer function (parse, load the config, call one function, print) that imports its
heavy libraries inside, so `deploy --help` stays instant.
"""

from __future__ import annotations

import os
import sys

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # BLAS threads busy-wait on small machines

import typer

from deploy.commands import arm, axis, bench, calibrate, cameras, perception, sim
from deploy.commands import open as open_commands
from deploy.commands.output import err_console
from deploy.errors import USER_ERRORS

app = typer.Typer(
    name="deploy", help="axisloop: open drawers and doors by estimating the joint axis online from RGB-D video.",
    no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False,
)
for _top_level in (open_commands.top_level, perception.top_level, cameras.top_level):
    app.add_typer(_top_level)  # no name: their commands join `deploy` itself
app.add_typer(axis.app, name="axis")
app.add_typer(sim.app, name="sim")
app.add_typer(bench.app, name="bench")
app.add_typer(perception.models_app, name="models")
app.add_typer(cameras.app, name="cameras")
app.add_typer(arm.app, name="arm")
app.add_typer(calibrate.app, name="calibrate")


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `deploy` script; returns the exit code. User errors become one red line (code 2)."""
    try:
        app(args=argv, prog_name="deploy")
    except SystemExit as exc:  # typer's standalone mode always ends here: usage errors, --help, Exit
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except USER_ERRORS as exc:
        err_console.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
