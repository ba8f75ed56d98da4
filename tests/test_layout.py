"""The layer rule and the import graph: drivers at the bottom; calibration and sim_fallback side by side above
it (neither imports the other); deploy on top. No import cycle between project modules, lazy imports inside
functions included (`if TYPE_CHECKING:` blocks excluded); typer only in the CLI; the real-arm bring-up path
loads neither PyBullet nor Open3D."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("deploy", "calibration", "sim_fallback", "drivers")
MAY_IMPORT = {  # each package may import only these project packages (besides itself)
    "drivers": set(),
    "calibration": {"drivers"},
    "sim_fallback": {"drivers"},
    "deploy": {"calibration", "sim_fallback", "drivers"},
}
CLI_PACKAGES = ("deploy.cli", "deploy.commands")


def _modules() -> dict[str, Path]:
    out = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            out[name.removesuffix(".__init__")] = path
    return out


MODULES = _modules()


def _resolve(name: str) -> str | None:
    """The project module `name` refers to (a `from package import symbol` resolves to the package)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _imports(module: str) -> set[str]:
    """Every name the module imports, anywhere in it (functions included), except under `if TYPE_CHECKING:`."""
    path = MODULES[module]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    guarded = [n for n in ast.walk(tree) if isinstance(n, ast.If) and "TYPE_CHECKING" in ast.unparse(n.test)]
    skipped = {id(n) for node in guarded for n in ast.walk(node)}
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    names = set()
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package[: len(package) - node.level + 1] + ([base] if base else []))
            names |= {base} | {f"{base}.{alias.name}" for alias in node.names}
    return names


GRAPH = {m: {t for t in map(_resolve, _imports(m)) if t and t != m} for m in MODULES}


@pytest.mark.parametrize("package", PACKAGES)
def test_a_package_imports_only_the_layers_it_may(package):
    offenders = {}
    for module in MODULES:
        if module.split(".")[0] != package:
            continue
        others = {name.split(".")[0] for name in _imports(module)} & set(PACKAGES) - {package}
        if others - MAY_IMPORT[package]:
            offenders[module] = sorted(others - MAY_IMPORT[package])
    assert not offenders, f"{package} may import only {sorted(MAY_IMPORT[package])}: {offenders}"


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def _reexports_only(component: list[str]) -> bool:
    """A package __init__ and one of its own submodules: a re-export, not a cycle worth naming."""
    root = min(component, key=len)
    return len(component) == 2 and all(m.startswith(root) for m in component)


def test_no_import_cycles_lazy_imports_included():
    cycles = [c for c in _cycles(GRAPH) if not _reexports_only(c)]
    assert not cycles, "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles)


def test_the_cycle_check_can_fail():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_typer_only_in_the_cli():
    users = [m for m in MODULES if any(n.split(".")[0] == "typer" for n in _imports(m))]
    assert users and all(m.startswith(CLI_PACKAGES) for m in users), users


REAL_DEVICE_COMMANDS = {  # each fails fast without the hardware (code 2), after its whole import path has loaded
    "arm bring-up": ["arm", "status", "--arm", "can", "--robot", "damiao_6dof"],  # no CAN adapter can0 here
    "calibration": ["calibrate", "hand-eye", "--camera", "d415:000000000000", "--arm", "can", "--robot", "damiao_6dof",
                    "--pivot-mm", "0", "0", "30", "--dry-run"],  # no camera has this serial
}


@pytest.mark.parametrize("args", REAL_DEVICE_COMMANDS.values(), ids=REAL_DEVICE_COMMANDS.keys())
def test_real_device_commands_load_neither_pybullet_nor_open3d(args, tmp_path):
    """The real CLI entry, as a user runs it: a top-level import of the simulator or of Open3D anywhere on the
    path (cli, command modules, rig, devices, drivers) fails this; so does a bus left open by a failed connect."""
    code = (
        "import sys\n"
        "from deploy.cli import main\n"
        f"code = main({args!r})\n"
        "print(code, sorted(m for m in ('pybullet', 'open3d') if m in sys.modules))\n"
    )
    env = {**os.environ, "AXISLOOP_CALIBRATION_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120, env=env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "2 []", out.stdout + out.stderr
    assert "error:" in out.stderr and "Traceback" not in out.stderr
    assert "not properly shut down" not in out.stderr, out.stderr
