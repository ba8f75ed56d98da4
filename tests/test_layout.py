"""Dependencies point one way: deploy -> calibration -> sim_fallback -> drivers."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ["deploy", "calibration", "sim_fallback", "drivers"]  # each may import only those after it


def imported_packages(path: Path) -> set[str]:
    """Top-level names of every module the file imports (anywhere in it, not only at the top)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package", LAYERS[1:])
def test_a_package_imports_no_layer_above_it(package):
    above = set(LAYERS[: LAYERS.index(package)])
    offenders = {
        str(path.relative_to(ROOT)): sorted(imported_packages(path) & above)
        for path in sorted((ROOT / package).rglob("*.py"))
        if imported_packages(path) & above
    }
    assert not offenders, f"{package} must not import {sorted(above)}: {offenders}"
