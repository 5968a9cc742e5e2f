"""The numba backend in a new process: its compiled model is restored from the authenticated disk
cache without deriving the equations again (issue 11), and a tampered entry is never used.

The entries are planted as docs/backends.md ("Model cache") describes them; the MACs are computed
by tests/test_cache_trust.py's ``signed`` with :mod:`hmac`, independently of
:mod:`multipole.cache`.  Expected numbers come from the closed form of a mass dragged through a
damper, v = F/d (1 - exp(-d t/m)).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba")

from multipole import pipeline  # noqa: E402
from multipole.backends import numba_backend  # noqa: E402
from multipole.netlist import load  # noqa: E402
from test_cache_trust import DRAG as DRAG_NUMPY, D, F, M, _data, _part, signed  # noqa: E402
from test_monitors import NETLIST as MONITORED, PERIOD, crossing_times, oscillator_type  # noqa: E402,F401

#: the drag scene of tests/test_cache_trust.py, run on the numba backend
DRAG = DRAG_NUMPY.replace("atol: 1.0e-13}", "atol: 1.0e-13, backend: numba}")
assert DRAG != DRAG_NUMPY
#: the runs use rtol 1e-10, atol 1e-13: the global error on v (at most F/d = 1.25 m/s) stays far below
TOL = 1e-7 * F / D


def exact(t):
    return F / D * (1 - np.exp(-D * np.asarray(t) / M))


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A netlist and a cache root shared by this module's tests (numba's machine code for the model
    is compiled once; every test starts from a genuine entry)."""
    base = tmp_path_factory.mktemp("numba_cache")
    netlist = base / "drag.yaml"
    netlist.write_text(DRAG)
    return netlist, base / "cache"


@pytest.fixture
def root(folders, monkeypatch):
    """The module's cache root, and empty in-memory caches before each run (as in a new process)."""
    netlist, folder = folders
    monkeypatch.setenv("MULTIPOLE_CACHE", str(folder))
    return folder


def forget():
    """Empty the pipeline's in-memory caches (analyses, equations, restored models), as in a new process."""
    for memo in (pipeline._CHECKED, pipeline._PRUNED, pipeline._RESTORED):
        memo.clear()


def run(netlist):
    """A run as in a new process (no analyses, equations or restored models in memory); asserts the
    closed form."""
    forget()
    res = pipeline.run(load(netlist), progress=False)
    assert res.stats["backend"] == "numba"
    assert np.max(np.abs(res["body.v"] - exact(res.t))) <= TOL
    return res


def entry_of(root) -> Path:
    (path,) = root.glob("numba-*.entry")
    return path


def genuine(root, netlist):
    """(entry path, user key, genuine payload as a dict), the entry written by a run if missing."""
    if not list(root.glob("numba-*.entry")):
        run(netlist)
    path = entry_of(root)
    run(netlist)                    # a genuine entry now, whatever an earlier test left
    return path, (root / "key").read_bytes(), json.loads(path.read_bytes().partition(b"\n")[2])


# -- a new process ----------------------------------------------------------------------------------

CHILD = textwrap.dedent("""
    import json, sys
    from multipole import pipeline
    from multipole.netlist import load
    res = pipeline.run(load(sys.argv[1]), progress=False)
    print(json.dumps({"derived": res.stats["equations_derived"], "backend": res.stats["backend"],
                      "t": res.t.tolist(), "v": res["body.v"].tolist()}))
""")


def test_a_new_process_runs_the_cached_model_without_deriving(tmp_path):
    netlist = tmp_path / "drag.yaml"
    netlist.write_text(DRAG)
    env = dict(os.environ, MULTIPOLE_CACHE=str(tmp_path / "cache"))
    runs = [json.loads(subprocess.run([sys.executable, "-c", CHILD, str(netlist)], env=env, check=True,
                                      capture_output=True, text=True).stdout) for _ in range(2)]
    assert [r["derived"] for r in runs] == [True, False]
    assert [r["backend"] for r in runs] == ["numba", "numba"]
    for r in runs:
        assert np.max(np.abs(np.array(r["v"]) - exact(r["t"]))) <= TOL
    assert runs[0]["t"] == runs[1]["t"]
    assert np.max(np.abs(np.array(runs[0]["v"]) - np.array(runs[1]["v"]))) <= TOL


def test_the_cli_restores_without_deriving(root, folders, monkeypatch):
    """``multipole simulate`` asks no stage before the run: a restored model derives nothing (every
    derivation starts with ``pipeline.check``, which counts it)."""
    from multipole.cli import main
    netlist, _ = folders
    genuine(root, netlist)
    forget()
    before = pipeline._DERIVATIONS[0]
    assert main(["simulate", str(netlist), "--quiet"]) == 0
    assert pipeline._DERIVATIONS[0] == before


def test_an_in_process_run_still_reports_derivation(root, folders):
    netlist, _ = folders
    for path in root.glob("numba-*.entry"):
        path.unlink()
    assert run(netlist).stats["equations_derived"]
    assert not run(netlist).stats["equations_derived"]


# -- tampered entries: refused, rebuilt, never run ----------------------------------------------------

_model = _part("model")


def _set(k, v):
    return lambda m: m.__setitem__(k, v)


TAMPERED = {
    # not authenticated: refused before anything is parsed
    "force doubled after signing": lambda p, k, d: signed(k, p.name, json.dumps(d).encode()).replace(
        b"push_u = 10.0", b"push_u = 20.0", 1),
    "MAC with another key": lambda p, k, d: signed(b"\0" * 32, p.name, json.dumps(d).encode()),
    "MAC of another file name": lambda p, k, d: signed(k, "numba-0.entry", json.dumps(d).encode()),
    "truncated": lambda p, k, d: signed(k, p.name, json.dumps(d).encode())[:300],
    "bare JSON": lambda p, k, d: json.dumps(d).encode(),
    # authenticated with the user's key, but of the wrong shape or made for other kernels
    "other kernels": _model(_set("kernels", "0" * 16)),
    "x0 too long": _model(lambda m: m["x0"].append(1.0)),
    "x0 of strings": _model(lambda m: m.__setitem__("x0", ["0"] * len(m["x0"]))),
    "one unit missing": _model(lambda m: m["units"].pop()),
    "a switch text too many": _model(lambda m: m["switch_text"].append("t - 1")),
    "source a syntax error": _model(lambda m: m.__setitem__("source", m["source"].replace("def rhs", "def rhs("))),
    "source without rhs": _model(lambda m: m.__setitem__("source", m["source"].replace("def rhs(", "def rhs_("))),
    "model missing": _data(lambda d: {k: v for k, v in d.items() if k != "model"}),
    "warnings a string": _data(lambda d: {**d, "warnings": "none"}),
    "states_pruned a bool": _data(lambda d: {**d, "states_pruned": False}),
    "JSON a list": _data(lambda d: list(d.values())),
}


@pytest.mark.parametrize("name", list(TAMPERED))
def test_a_tampered_entry_is_refused_and_rebuilt(root, folders, name):
    netlist, _ = folders
    path, key, data = genuine(root, netlist)
    planted = TAMPERED[name](path, key, data)
    assert planted != path.read_bytes()
    path.write_bytes(planted)
    assert run(netlist).stats["equations_derived"]
    assert not run(netlist).stats["equations_derived"]       # rewritten: the next process restores it


def _planted(data, marker: Path) -> dict:
    planted = json.loads(json.dumps(data))
    planted["model"]["source"] = f"open({str(marker)!r}, 'w').write('ran')\n" + planted["model"]["source"]
    return planted


@pytest.mark.parametrize("how", ["forged MAC", "MAC with another key", "bare JSON"])
def test_planted_code_never_runs(root, folders, tmp_path, how):
    netlist, _ = folders
    marker = tmp_path / "marker"
    path, key, data = genuine(root, netlist)
    payload = json.dumps(_planted(data, marker)).encode()
    path.write_bytes({"forged MAC": b"multipole-cache-1 " + b"0" * 64 + b"\n" + payload,
                      "MAC with another key": signed(os.urandom(32), path.name, payload),
                      "bare JSON": payload}[how])
    assert run(netlist).stats["equations_derived"]
    assert not marker.exists()


def test_planted_code_would_run_if_it_were_signed(root, folders, tmp_path):
    """The control: an entry signed with the user's key sits where the model is looked up and is
    run, so the refused ones above fail only for what is wrong with them."""
    netlist, _ = folders
    marker = tmp_path / "marker"
    path, key, data = genuine(root, netlist)
    path.write_bytes(signed(key, path.name, json.dumps(_planted(data, marker)).encode()))
    assert not run(netlist).stats["equations_derived"]
    assert marker.read_text() == "ran"


def test_no_entry_without_a_disk_cache(monkeypatch, folders):
    netlist, _ = folders
    monkeypatch.setenv("MULTIPOLE_CACHE", "off")
    assert run(netlist).stats["equations_derived"]
    assert run(netlist).stats["equations_derived"]       # nothing on disk: a new process derives again


def test_describe_and_restore_round_trip(root, folders):
    """What the entry keeps rebuilds the same model: names, units, initial state, switch texts."""
    netlist, _ = folders
    eq, outs, _record = pipeline.pruned(load(netlist))
    first = numba_backend.run.compile(eq, outs)
    again = numba_backend.run.restore(numba_backend.run.describe(eq, outs))
    for attr in ("name", "state_names", "output_names", "output_units", "switch_text"):
        assert getattr(again, attr) == getattr(first, attr), attr
    assert np.array_equal(again.x0, first.x0)
    assert numba_backend.run.describe(eq, ["body.p"]) is None      # not the outputs it was compiled for


def test_a_restored_model_keeps_its_monitors(root, tmp_path, oscillator_type):
    """The monitors live in the generated module: restored from the entry, the model reports the
    same crossings, at the closed-form times of tests/test_monitors.py."""
    path = tmp_path / "watched.yaml"
    path.write_text(MONITORED.replace("STOP", "false"))
    runs = []
    for derived in (True, False):
        forget()
        res = pipeline.run(load(path), progress=False, backend="numba")
        assert res.stats["backend"] == "numba" and res.stats["equations_derived"] is derived
        runs.append(res.monitors)
    expected = crossing_times(0.05, 2.2 * PERIOD)
    assert runs[0] == runs[1] and len(runs[0]) == len(expected) == 3
    for (t, el, code, _text), t_exact in zip(runs[0], expected):
        assert (el, code) == ("osc", "passed_x0") and abs(t - t_exact) <= 5e-6 * t_exact
