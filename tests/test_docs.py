"""The CLI reference in docs/ is generated from the code: regenerate it when a command changes."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_cli_reference_is_current(tmp_path):
    out = tmp_path / "cli.md"
    subprocess.run(
        [sys.executable, "-m", "typer", "deploy.cli", "utils", "docs", "--name", "deploy", "--output", str(out)],
        check=True, cwd=ROOT, capture_output=True,
    )
    assert out.read_text() == (ROOT / "docs" / "cli.md").read_text(), (
        "docs/cli.md is out of date: run `.venv/bin/python -m typer deploy.cli utils docs --name deploy "
        "--output docs/cli.md`"
    )


def test_readme_starts_with_the_two_commands():
    text = (ROOT / "README.md").read_text()
    blocks = [b.split("```")[0].strip() for b in text.split("```bash\n")[1:3]]
    assert blocks[0].startswith("bash scripts/setup.sh && .venv/bin/deploy ")
    assert blocks[1] == ".venv/bin/python -m pytest -n 2"
    assert blocks[1] in (ROOT / ".ci" / "run").read_text()


def test_quickstart_config_loads_and_its_commands_exist(tmp_path):
    from deploy.config import load_config

    text = (ROOT / "docs" / "quickstart.md").read_text()
    (tmp_path / "first-day.toml").write_text(text.split("```toml\n")[1].split("```")[0])
    config = load_config(tmp_path / "first-day.toml")
    assert config.filter.profile == "sparse" and config.opening.timeout_s == 120
    assert config.perception.object_prompt == "drawer"
    commands = {line.split()[1] for line in text.splitlines() if line.startswith("deploy ")}
    assert {"open-drawer", "cameras", "calibrate", "record", "export", "arm"} <= commands
