"""Generate docs/cli.md, the CLI reference, from the code: `.venv/bin/python scripts/cli_docs.py`.

typer's own generator (`typer deploy.cli utils docs`) renders help texts through rich's HTML export, which turns
every quote into `&#x27;` / `&quot;`; this writes them back as plain quotes (`&lt;`, `&gt;` and `&amp;` stay
escaped: Markdown would read them as HTML). tests/test_docs.py checks that docs/cli.md is current.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "cli.md"
PLAIN = {"&#x27;": "'", "&quot;": '"'}


def cli_reference() -> str:
    """docs/cli.md's text, as typer's generator writes it but with plain quotes."""
    import typer
    from typer.cli import get_docs_for_click
    from typer.main import get_command

    from deploy.cli import app

    command = get_command(app)
    ctx = typer.Context(command, info_name="deploy", obj={"TYPER_RICH_MARKUP_MODE": "rich"})
    text = get_docs_for_click(obj=command, ctx=ctx, name="deploy", title="`deploy`")
    for entity, plain in PLAIN.items():
        text = text.replace(entity, plain)
    return text.strip() + "\n"


def main(argv: list[str]) -> int:
    out = Path(argv[0]) if argv else OUT
    out.write_text(cli_reference())
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main(sys.argv[1:]))
