"""The command outputs shown in the docs are what the CLI prints now (tools/refresh_doc_outputs.py
rewrites them).

What is compared is what does not depend on the machine: the text with every number taken out must
be the same, and the numbers must agree to the precision they are printed with (relative 1e-12 for
a printed float, half a unit of the last printed digit for a rounded one).  Solver counters
(steps, rejected, nfev, njev, nlu) depend on the BLAS kernel and the CPU: they are compared within
:data:`COUNTER_BOUND`; wall and compile times (or "model from cache") not at all.
"""
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
from refresh_doc_outputs import blocks, command_output  # noqa: E402

PAGES = ["docs/getting-started.md", "docs/linkages.md"]
NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
TIMING = re.compile(r"wall [0-9.e+-]+ s(, compile [0-9.e+-]+ s|, model from cache)?")
#: Relative bound on a solver counter between the documented run and this machine's.
COUNTER_BOUND = 0.25
COUNTERS = ("steps", "rejected", "nfev", "njev", "nlu")


def _skeleton(text: str):
    """(text with numbers replaced by '#', [(number text, the word before it)])."""
    text = TIMING.sub("wall … s", text)
    numbers = [(m.group(), re.findall(r"[\w|*]+", text[max(0, m.start() - 20):m.start()])[-1:])
               for m in NUMBER.finditer(text)]
    return NUMBER.sub("#", text), [(n, w[0] if w else "") for n, w in numbers]


def _close(shown: str, now: str, word: str) -> bool:
    a, b = float(shown), float(now)
    if word in COUNTERS:
        return abs(a - b) <= COUNTER_BOUND * max(abs(a), 4.0)
    digits = re.sub(r"[eE].*", "", shown.lstrip("+-")).replace(".", "").lstrip("0")
    exponent = int(shown.split("e")[1]) if "e" in shown.lower() else 0
    decimals = len(shown.lower().split("e")[0].partition(".")[2])
    half_unit = 0.5 * 10.0 ** (exponent - decimals) if len(digits) < 15 else 0.0
    return abs(a - b) <= max(half_unit, 1e-12 * max(abs(a), abs(b)))


def assert_same_output(shown: str, now: str) -> None:
    """The two outputs differ at most in machine-dependent numbers (see the module docstring)."""
    (s_text, s_nums), (n_text, n_nums) = _skeleton(shown), _skeleton(now)
    assert n_text == s_text
    for (a, word), (b, _) in zip(s_nums, n_nums):
        assert _close(a, b, word), f"{word} {a} documented, {b} now"


CASES = [(page, cmd, shown) for page in PAGES for cmd, shown in blocks((ROOT / page).read_text(encoding="utf-8"))]


@pytest.mark.parametrize("page, command, shown", CASES, ids=[f"{p}: {c[:60]}" for p, c, _ in CASES])
def test_documented_output_matches_the_cli(page, command, shown, tmp_path):
    if " simulate " in command:          # write its files into a scratch folder, compare the summary
        command = re.sub(r"--(out|plot) (\S+)", lambda m: f"--{m.group(1)} {tmp_path / Path(m.group(2)).name}",
                         command)
        assert_same_output(shown.splitlines()[0], command_output(command).splitlines()[0])
        return
    assert_same_output(shown, command_output(command))


SUMMARY = ("drive_train: solver DOP853 (non-stiff: |lambda|max*t_end = 679, stiffness ratio 220), steps 211, "
           "rejected 19, nfev 3392, njev 0, nlu 0, events 0, wall 0.0287 s, model from cache")


@pytest.mark.parametrize("now, same", [
    (SUMMARY.replace("wall 0.0287 s, model from cache", "wall 1.5 s, compile 0.2 s"), True),    # cache: timing
    (SUMMARY.replace("wall 0.0287", "wall 3.1"), True),                                      # timing: ignored
    (SUMMARY.replace("rejected 19, nfev 3392", "rejected 18, nfev 3380"), True),              # other BLAS
    (SUMMARY.replace("nfev 3392", "nfev 5000"), False),                                       # beyond the bound
    (SUMMARY.replace("= 679", "= 679.2"), True),                                              # rounded: half a unit
    (SUMMARY.replace("= 679", "= 680"), False),
    (SUMMARY.replace("events 0", "events 1"), False),                                         # not a counter
    (SUMMARY.replace("DOP853", "RK45"), False),
    ("x = 0.06666666666666667*t", True), ("x = 0.06666666676666665*t", False),      # 16 digits: 1e-12
])
def test_output_comparison_ignores_only_what_the_machine_changes(now, same):
    shown = "x = 0.06666666666666665*t" if now.startswith("x =") else SUMMARY
    try:
        assert_same_output(shown, now)
        result = True
    except AssertionError:
        result = False
    assert result == same
