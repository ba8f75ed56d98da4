"""The CLI reference in docs/ is generated from the code: regenerate it when a command changes."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_cli_reference_is_current(tmp_path):
    out = tmp_path / "cli.md"
    subprocess.run([sys.executable, "scripts/cli_docs.py", str(out)], check=True, cwd=ROOT, capture_output=True)
    text = out.read_text()
    assert text == (ROOT / "docs" / "cli.md").read_text(), (
        "docs/cli.md is out of date: run `.venv/bin/python scripts/cli_docs.py`"
    )
    assert "&#x27;" not in text and "&quot;" not in text  # plain quotes, not HTML entities
    assert "[filter] (profile, radius_m, eps) [geometry] [estimator] [opening]" in text  # brackets kept, not markup
    assert "Configuration in docs/quickstart.md" in text


def test_doc_links_name_sections_that_exist():
    """Every `docs/FILE.md#anchor` written in the code or the docs names a heading of that file."""
    import re

    sources = [*ROOT.glob("deploy/**/*.py"), *ROOT.glob("docs/*.md")]
    links = {m for path in sources for m in re.findall(r"docs/([\w-]+\.md)#([\w-]+)", path.read_text())}
    links |= {(name, anchor) for name, anchor in re.findall(r"\]\(([\w-]+\.md)#([\w-]+)\)",
                                                             (ROOT / "docs" / "quickstart.md").read_text())}
    assert ("quickstart.md", "configuration") in links
    for name, anchor in sorted(links):
        headings = re.findall(r"^#+ (.+)$", (ROOT / "docs" / name).read_text(), re.MULTILINE)
        slugs = {re.sub(r"[^\w\- ]", "", h).strip().lower().replace(" ", "-") for h in headings}
        assert anchor in slugs, f"docs/{name}#{anchor}: no such section (sections: {sorted(slugs)})"


def test_readme_starts_with_the_two_commands():
    text = (ROOT / "README.md").read_text()
    blocks = [b.split("```")[0].strip() for b in text.split("```bash\n")[1:3]]
    assert blocks[0].startswith("bash scripts/setup.sh && .venv/bin/deploy ")
    assert blocks[1] == ".venv/bin/python -m pytest -n 2"
    assert blocks[1] in (ROOT / ".ci" / "run").read_text()


def _quickstart_commands() -> list[list[str]]:
    """Every `deploy ...` command line of docs/quickstart.md's code blocks, split as the shell would (comments
    dropped, `&&` chains split)."""
    import shlex

    text = (ROOT / "docs" / "quickstart.md").read_text()
    lines = [line for block in text.split("```")[1::2] for line in block.splitlines()]
    commands = []
    for line in lines:
        words = shlex.split(line, comments=True)
        while "&&" in words:
            at = words.index("&&")
            commands.append(words[:at])
            words = words[at + 1:]
        commands.append(words)
    return [words[1:] for words in commands if words[:1] == ["deploy"]]


def _parse(args: list[str]) -> str:
    """Parse `deploy ARGS` with the CLI's own parser, down to the command, as the shell would hand them over
    (unknown options, missing arguments, bad values fail); the command's path."""
    import typer

    from deploy.cli import app

    command, path, rest = typer.main.get_command(app), "deploy", list(args)
    while True:
        try:
            ctx = command.make_context(path, list(rest), resilient_parsing=False)
        except typer.Exit:  # an eager option such as --version ran
            return path
        if not hasattr(command, "resolve_command"):  # a command, not a group
            return path
        rest = [*ctx._protected_args, *ctx.args]
        if not rest:
            return path
        name, command, rest = command.resolve_command(ctx, rest)
        path = f"{path} {name}"


def test_quickstart_config_loads_and_its_commands_parse(tmp_path):
    from deploy.config import load_config

    text = (ROOT / "docs" / "quickstart.md").read_text()
    (tmp_path / "first-day.toml").write_text(text.split("```toml\n")[1].split("```")[0])
    config = load_config(tmp_path / "first-day.toml")
    assert config.filter.profile == "sparse" and config.opening.timeout_s == 120
    assert config.perception.object_prompt == "drawer"
    commands = _quickstart_commands()
    paths = {_parse(args) for args in commands}  # an unknown option or a bad value raises here
    assert {"deploy open-drawer", "deploy cameras list", "deploy calibrate hand-eye", "deploy record",
            "deploy export", "deploy arm status"} <= paths
    assert len(commands) >= 30


def test_parsing_quickstart_commands_catches_unknown_options():
    import typer

    assert _parse(["open-drawer", "--camera", "d415", "--dry-run"]) == "deploy open-drawer"
    assert _parse(["--version"]) == "deploy"
    with pytest.raises(typer.TyperException, match="No such option"):
        _parse(["open-drawer", "--no-such-option"])
    with pytest.raises(typer.BadParameter):
        _parse(["open-door", "--angle", "wide"])
    with pytest.raises(typer.TyperException, match="No such command"):
        _parse(["open-window"])


def test_readme_names_every_segmenter_track_takes():
    """README's `deploy track` row lists the --segmenter choices the command takes, no more, no fewer."""
    import re

    from deploy.perception.registry import SEGMENTERS

    row = next(line for line in (ROOT / "README.md").read_text().splitlines() if line.startswith("| `deploy track"))
    listed = re.search(r"--segmenter ([\w\\|-]+)", row).group(1).replace("\\", "").split("|")
    assert sorted(listed) == sorted(SEGMENTERS.names())

