"""Running `deploy` in-process in tests: its exit code, stdout and stderr, and its one-line errors."""

from deploy.cli import main


def run(capsys, *args) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def one_line(err: str) -> str:
    """The error line of `err`, asserting it is the only line, starts with "error: " and holds no traceback."""
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, err
    return lines[0]


def small_recording(path):
    """`deploy record` of the simulated camera at `path` in the box world (one cabinet): 6 frames of 160x120, no
    masks; returns `path`."""
    assert main(["record", "--camera", "sim", "--world", "box", "--out", str(path), "--frames", "6", "--width", "160",
                 "--height", "120"]) == 0
    return path
