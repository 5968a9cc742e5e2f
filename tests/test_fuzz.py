"""Fuzzing in the suite: generated and mutated netlists through ``check``, ``simulate`` and ``equations``.

The generator is the one of ``tools/fuzz_campaign.py`` (which runs it at scale, see docs/testing.md):
even cases are generated scenes (random catalogue elements, parameters of every kind, connections
mostly within a domain), odd cases are the scenes of ``diagrams/`` with random deletions, type swaps,
values of the wrong kind or size, and text-level damage (YAML tags, duplicated keys, deep nesting,
alias bombs, bytes that are not UTF-8).  Every case runs in this process through
``multipole.cli.main`` under a per-case alarm and must end with exit code 0, 1, 2 or 3, no traceback,
and an exit 2/3 with exactly one ``error[...]`` line on stderr (and nothing before it).

Seeded, so a failure names a case that reproduces: ``netlist(SEED, index)`` writes it again, and the
failing inputs are also written to the test's tmp_path.  Sized for CI: well under a minute.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("fuzz_campaign", ROOT / "tools" / "fuzz_campaign.py")
fuzz = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fuzz)

SEED = 1
CASES = {"check": 300, "simulate": 60, "equations": 60}
TIME_CAP = 20.0           # seconds per case; slowest measured: 6.6 s wall (0.9 s CPU) on a loaded machine


@pytest.mark.parametrize("verb", sorted(CASES))
def test_fuzzed_netlists_end_in_one_clean_line(verb, tmp_path):
    files = fuzz.scene_files()
    failures, exits = [], set()
    for index in range(CASES[verb]):
        data = fuzz.netlist(SEED, index, files)
        path = tmp_path / f"case{index}.yaml"
        path.write_bytes(data if isinstance(data, bytes) else data.encode())
        outcome, code, printed = fuzz.run_case(verb, str(path), TIME_CAP)
        exits.add(code)
        if outcome != "ok":
            failures.append(f"case {index} ({'generated' if index % 2 == 0 else 'mutated'}, {path}): {outcome}, "
                            f"exit {code}: {printed.strip().splitlines()[-1] if printed.strip() else ''}")
        else:
            path.unlink()
    assert not failures, f"{len(failures)} of {CASES[verb]} cases failed:\n" + "\n".join(failures[:10])
    # the generator reaches every outcome a user can meet, not only refusals
    assert {0, 1, 2} <= exits, exits


def test_cases_are_reproducible():
    """The same seed and index give the same netlist (a failure can be re-run from its number)."""
    files = fuzz.scene_files()
    for index in range(6):
        assert fuzz.netlist(SEED, index, files) == fuzz.netlist(SEED, index, files)
    assert fuzz.netlist(SEED, 0, files) != fuzz.netlist(SEED + 1, 0, files)


def test_the_checker_catches_what_it_hunts(tmp_path, monkeypatch):
    """run_case classifies an escaping exception, a hang, a wrong exit code and a second error line."""
    import multipole.cli as cli
    path = tmp_path / "x.yaml"
    path.write_text("name: x\n")

    def boom(argv):
        raise ZeroDivisionError("inside the kernel")

    def hang(argv):
        while True:
            pass

    def two_lines(argv):
        import sys
        print("error[a] first", file=sys.stderr)
        print("error[b] second", file=sys.stderr)
        return 2

    def preceded(argv):
        import sys
        print("RuntimeWarning: overflow encountered", file=sys.stderr)
        print("error[a] the one line", file=sys.stderr)
        return 3

    def nan_result(argv):
        print("final values: x = nan")
        return 0

    for fake, outcome in ((boom, "traceback"), (hang, "hang"), (lambda argv: 7, "exit_code"),
                          (two_lines, "output"), (preceded, "output"), (nan_result, "wrong_result")):
        monkeypatch.setattr(cli, "main", fake)
        verb = "simulate" if fake is nan_result else "check"
        assert fuzz.run_case(verb, str(path), 0.5)[0] == outcome, fake
