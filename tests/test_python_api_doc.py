"""docs/python-api.md runs: its ```python blocks are executed in order in one namespace, in a scratch
folder holding a copy of diagrams/, and what each prints is compared with the ```output block that
follows it (numbers to the precision printed, as for the CLI outputs of docs/getting-started.md)."""
from __future__ import annotations

import contextlib
import io
import re
import shutil
from pathlib import Path

from test_docs import assert_same_output

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "python-api.md"
FENCE = re.compile(r"^```(\w+)\n(.*?)^```\s*$", re.S | re.M)


def fenced_blocks(text: str) -> list[tuple[str, str, int]]:
    """``[(language, body, line number), ...]`` of the page's fenced blocks, in order."""
    return [(m.group(1), m.group(2), text.count("\n", 0, m.start()) + 1) for m in FENCE.finditer(text)]


def _lines(text: str) -> str:
    return "\n".join(line.rstrip() for line in text.strip().splitlines())


def test_fenced_blocks_are_found():
    blocks = fenced_blocks("text\n```python\nprint(1)\n```\n\n```output\n1\n```\n")
    assert blocks == [("python", "print(1)\n", 2), ("output", "1\n", 6)]


def test_python_api_page_runs(tmp_path, monkeypatch):
    shutil.copytree(ROOT / "diagrams", tmp_path / "diagrams")
    monkeypatch.chdir(tmp_path)
    blocks = fenced_blocks(PAGE.read_text(encoding="utf-8"))
    code = [b for b in blocks if b[0] == "python"]
    assert len(code) >= 6, "the page lost its examples"
    namespace: dict = {"__name__": "python_api_doc"}
    printed = None
    compared = 0
    for language, body, line in blocks:
        if language == "python":
            out = io.StringIO()
            with contextlib.redirect_stdout(out):
                exec(compile(body, f"{PAGE.name}:{line}", "exec"), namespace)
            printed = out.getvalue()
        elif language == "output":
            assert printed is not None, f"{PAGE.name}:{line}: an output block without a python block before it"
            try:
                assert_same_output(_lines(body), _lines(printed))
            except AssertionError as exc:
                raise AssertionError(f"{PAGE.name}:{line}: the page shows\n{body}\nthe code prints\n{printed}") \
                    from exc
            compared += 1
            printed = None
    assert compared >= 6, "the page lost its outputs"
    assert (tmp_path / "drive_train.csv").exists() and (tmp_path / "drive_train.png").stat().st_size > 10_000
