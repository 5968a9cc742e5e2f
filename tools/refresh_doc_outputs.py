"""Refresh the ``$ multipole ...`` output blocks of a markdown page with what the CLI prints now.

    python tools/refresh_doc_outputs.py docs/getting-started.md

A fenced block whose first line is ``$ multipole ARGS`` is replaced by that command's output, run
from the repository root.  A block whose command ends in ``# from LINE`` keeps the output from the
first line that starts with LINE (an excerpt).  ``tests/test_docs.py`` checks the pages against
the CLI with the same rules, so a page that drifts fails the tests.
"""
from __future__ import annotations

import contextlib
import io
import re
import shlex
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"```\n\$ (multipole [^\n]*)\n(.*?)```", re.S)


def command_output(command: str) -> str:
    """Standard output of ``multipole ARGS [# from LINE]`` run in-process from the repository root."""
    from multipole.cli import main
    args, _, start = command.partition("# from ")
    out = io.StringIO()
    with contextlib.chdir(ROOT), contextlib.redirect_stdout(out):
        main(shlex.split(args)[1:])
    text = out.getvalue()
    if start.strip():
        text = text[text.index("\n" + start.strip()) + 1:]
    return text if text.endswith("\n") else text + "\n"


def blocks(page: str) -> list[tuple[str, str]]:
    """(command, shown output) of every command block of a page."""
    return [(m.group(1), m.group(2)) for m in BLOCK.finditer(page)]


def refresh(path: Path) -> None:
    page = path.read_text(encoding="utf-8")
    path.write_text(BLOCK.sub(lambda m: f"```\n$ {m.group(1)}\n{command_output(m.group(1))}```", page),
                    encoding="utf-8")


if __name__ == "__main__":
    for name in sys.argv[1:]:
        refresh(Path(name))
        print(f"refreshed {name}")
