"""The `deploy` command line: the command groups of deploy/commands/ assembled into one app, and `main()`.

Each command is a thin typer function (parse, load the config, call one function, print) that imports its
heavy libraries inside, so `deploy --help` stays instant.

`deploy --verbose` logs at INFO (our packages at DEBUG) on stderr: the resolved run config, the devices opened,
the calibration file and camera pose source, the first detection, the grasp and every estimate; without it only
warnings and the episode's step lines are logged (one line each, whatever the width). `deploy --version` prints
the installed version.

`main()` ends every failure with one line on stderr naming the thing, the cause and the fix (the traceback
only with `deploy --verbose`), and with `--json` also a JSON error object on stdout that holds the final state
of every motor. Exit codes: 0 done, 1 the command ran and failed (an episode fell short, nothing answered, a
bug), 2 bad input (an option, a file, a device that refuses), 128 + N stopped by signal N (130 Ctrl-C, 143
SIGTERM). Every float option refuses nan and inf.
"""

from __future__ import annotations

import math
import os
import sys
import traceback
from collections.abc import Callable
from typing import Annotated, Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # BLAS threads busy-wait on small machines

import typer
from rich.markup import escape

from deploy.commands import arm, axis, bench, calibrate, cameras, perception, sim
from deploy.commands import open as open_commands
from deploy.commands.output import configure_logging, console, err_console, print_json
from deploy.errors import USER_ERRORS
from drivers.interrupts import Interrupted, interrupts, received

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

_options = {"verbose": False}


def _print_version(value: bool) -> None:
    if value:
        from importlib.metadata import version

        console.print(f"axisloop {version('axisloop')}", highlight=False)
        raise typer.Exit()


@app.callback()
def _global_options(
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="Log what a run uses and finds on stderr (the "
                                          "resolved config, devices, calibration file, detections, grasp, every "
                                          "estimate; INFO, our packages at DEBUG); on an error, print the traceback "
                                          "too.")] = False,
    version: Annotated[bool, typer.Option("--version", callback=_print_version, is_eager=True,
                                          help="Print the installed version and exit.")] = False,
) -> None:
    _options["verbose"] = verbose
    configure_logging(verbose)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `deploy` script; returns the exit code (see the module docstring)."""
    args = sys.argv[1:] if argv is None else list(argv)
    _options["verbose"] = False
    command = build_command()
    try:
        with interrupts():
            code = command.main(args=args, prog_name="deploy", standalone_mode=False)
    except typer.TyperException as exc:  # a usage error: unknown option, bad or missing value
        if type(exc).__name__ == "NoArgsIsHelpError":
            return exc.exit_code  # the help was printed
        ctx = getattr(exc, "ctx", None)
        where = f" (see `{ctx.command_path} --help`)" if ctx is not None else ""
        return _fail(exc, f"{exc.format_message()}{where}", exc.exit_code, args)
    except typer.Abort as exc:  # a question answered no, or met the end of standard input
        if isinstance(exc.__context__, EOFError):
            return _fail(exc, "no answer to the question (standard input is closed): pass --yes to skip it", 1, args)
        return _fail(exc, "aborted: the question was answered no", 1, args)
    except Interrupted as exc:
        return _fail(exc, _interrupted(exc), exc.exit_code, args)
    except USER_ERRORS as exc:
        return _fail(exc, _with_motors(str(exc), exc), 2, args)
    except OSError as exc:  # a path that cannot be read or written, a full disk
        where = f"{exc.filename}: " if exc.filename else ""
        return _fail(exc, _with_motors(f"{where}{exc.strerror or exc}: check the path, its permissions and the free "
                                       "space", exc), 2, args)
    except Exception as exc:  # noqa: BLE001 - a bug: one line, the traceback with --verbose
        if (signum := received()) is not None:  # a signal during an import can surface as an ImportError
            stop = Interrupted(signum)
            return _fail(exc, _interrupted(stop), stop.exit_code, args)
        return _fail(exc, f"internal error ({type(exc).__name__}: {exc}): please report it with the output of "
                     f"`deploy --verbose {' '.join(args)}`", 1, args)
    return code if isinstance(code, int) else 0


def _fail(exc: BaseException, line: str, code: int, args: list[str]) -> int:
    """Print `line` (and the traceback with --verbose; the JSON error object with --json); return `code`."""
    if _options["verbose"]:
        traceback.print_exception(exc)
    err_console.print(f"[bold red]error:[/] {escape(line)}", highlight=False, soft_wrap=True, emoji=False)
    if "--json" in args:
        print_json({"error": line, "kind": type(exc).__name__, "exit_code": code,
                    "motors": getattr(exc, "motors", [])})
    return code


def _with_motors(message: str, exc: BaseException) -> str:
    """`message` with what happened to the motors, when an arm's motors went with the exception."""
    motors = getattr(exc, "motors", None)
    if not motors:
        return message
    from drivers.arm.disable import with_summary

    return with_summary(message, motors)


def _interrupted(exc: Interrupted) -> str:
    """What stopped, the motors, and where the run folder is."""
    line = _with_motors(exc.message, exc)
    if exc.result is not None and not getattr(exc, "motors", None):
        line += "; arm stopped"
    if exc.run_dir is not None:
        line += f"; the run folder {exc.run_dir} holds the frames, steps.json and report.png up to here"
    return line


def build_command() -> Any:
    """The click command of `app` as `main()` runs it: numbers refuse nan and inf, flags show no value."""
    command = typer.main.get_command(app)
    _finite_numbers(command)
    _plain_flags(command)
    return command


def _plain_flags(command: Any) -> None:
    """Show every on/off flag of `command` and its subcommands (--json, --help, ...) without a value type in the
    help: typer's rich help prints `--json <bool>`, which reads as if `--json true` were accepted."""
    for param in command.params:
        if getattr(param, "is_flag", False) and not getattr(param, "count", False):
            param.metavar = ""
    get_help_option = command.get_help_option

    def help_option(ctx: Any) -> Any:
        option = get_help_option(ctx)
        if option is not None:
            option.metavar = ""
        return option

    command.get_help_option = help_option
    for sub in getattr(command, "commands", {}).values():
        _plain_flags(sub)


def _finite_numbers(command: Any) -> None:
    """Make every option and argument of `command` and its subcommands refuse nan and inf (typer accepts them)."""
    for param in command.params:
        param.process_value = _finite(param, param.process_value)
    for sub in getattr(command, "commands", {}).values():
        _finite_numbers(sub)


def _finite(param: Any, process: Callable[[Any, Any], Any]) -> Callable[[Any, Any], Any]:
    """`process` (a parameter's value conversion) failing as a usage error on a number that is not finite."""

    def checked(ctx: Any, value: Any) -> Any:
        value = process(ctx, value)
        numbers = value if isinstance(value, (list, tuple)) else [value]
        bad = [v for v in numbers if isinstance(v, float) and not math.isfinite(v)]
        if bad:
            raise typer.BadParameter(f"{bad[0]} is not a finite number", ctx=ctx, param=param)
        return value

    return checked


if __name__ == "__main__":
    sys.exit(main())
