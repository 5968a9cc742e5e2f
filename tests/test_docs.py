"""The command outputs shown in the docs are what the CLI prints now (tools/refresh_doc_outputs.py
rewrites them); timings are the only thing allowed to differ."""
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
from refresh_doc_outputs import blocks, command_output  # noqa: E402

PAGES = ["docs/getting-started.md"]
TIMING = re.compile(r"wall [0-9.e+-]+ s(, compile [0-9.e+-]+ s|, model from cache)?")


def _normal(text: str) -> str:
    return TIMING.sub("wall … s", text)


CASES = [(page, cmd, shown) for page in PAGES for cmd, shown in blocks((ROOT / page).read_text(encoding="utf-8"))]


@pytest.mark.parametrize("page, command, shown", CASES, ids=[f"{p}: {c[:60]}" for p, c, _ in CASES])
def test_documented_output_matches_the_cli(page, command, shown, tmp_path, monkeypatch):
    if " simulate " in command:          # write its files into a scratch folder, compare the summary
        command = re.sub(r"--(out|plot) (\S+)", lambda m: f"--{m.group(1)} {tmp_path / Path(m.group(2)).name}",
                         command)
        now = command_output(command).splitlines()[0]
        assert _normal(now) == _normal(shown.splitlines()[0])
        return
    assert command_output(command) == shown
