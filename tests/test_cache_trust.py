"""The disk caches hold code, so only trusted code is ever run from them (issue 9 §1).

Entries are planted the way docs/backends.md ("Model cache") describes the layout; the MACs the
tests compute are computed here with :mod:`hmac`, independently of :mod:`multipole.cache`.
Expected numbers come from the closed form of a mass dragged through a damper.
"""
from __future__ import annotations

import hashlib
import hmac
import json
import os
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from multipole import cache, pipeline
from multipole.cli import main
from multipole.netlist import load

ROOT = Path(__file__).resolve().parents[1]

M, D, F = 2.0, 8.0, 10.0
DRAG = f"""
name: drag
parameters: {{m: {M}, d: {D}, F: {F}}}
elements:
  push:   {{type: force_source, value: "F"}}
  body:   {{type: mass, m: m}}
  damper: {{type: damper, d: d, domain: translational}}
  wall:   {{type: ground, domain: translational}}
connections:
  - [push.p, body.a]
  - [body.b, damper.a]
  - [damper.b, wall.p]
outputs: [body.v]
simulate: {{t_end: 1.0, dt_out: 0.01, rtol: 1.0e-10, atol: 1.0e-13}}
"""


@pytest.fixture
def netlist(tmp_path):
    path = tmp_path / "drag.yaml"
    path.write_text(DRAG)
    return path


@pytest.fixture
def root(tmp_path, monkeypatch):
    """A cache root of this test only, and empty in-memory caches (as in a new process)."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("MULTIPOLE_CACHE", str(folder))
    pipeline._MODELS.clear()
    cache._WARNED.clear()
    yield folder
    pipeline._MODELS.clear()


def simulate(netlist):
    """A run as in a new process; asserts the closed form v = F/d (1 - exp(-d t/m))."""
    pipeline._MODELS.clear()
    res = pipeline.run(load(netlist), progress=False)
    exact = F / D * (1 - np.exp(-D * res.t / M))
    assert res.t[-1] == pytest.approx(1.0)
    assert np.max(np.abs(res["body.v"] - exact)) <= 1e-7 * F / D
    return res


def entry_of(root) -> Path:
    (path,) = root.glob("model-*.entry")
    return path


def signed(key: bytes, name: str, payload: bytes) -> bytes:
    """An entry as docs/backends.md describes it: magic, MAC over name + newline + payload."""
    mac = hmac.new(key, name.encode() + b"\n" + payload, hashlib.sha256).hexdigest()
    return b"multipole-cache-1 " + mac.encode() + b"\n" + payload


def genuine(root):
    """(entry path, user key, genuine payload as a dict) after one run that wrote the entry."""
    path = entry_of(root)
    key = (root / "key").read_bytes()
    payload = path.read_bytes().partition(b"\n")[2]
    return path, key, json.loads(payload)


# -- damaged entries: rebuilt, never a crash ---------------------------------------------------------

def _part(name):
    """A planter that applies ``change`` to the payload's part ``name`` and signs the result."""
    def changed(change):
        def plant(path, key, data):
            data = json.loads(json.dumps(data))
            change(data[name])
            return signed(key, path.name, json.dumps(data).encode())
        return plant
    return changed


_meta = _part("meta")


def _data(value):
    return lambda path, key, data: signed(key, path.name, json.dumps(value(data)).encode())


def _raw(blob):
    return lambda path, key, data: blob(path, key, data)


def _set(k, v):
    def change(meta):
        meta[k] = v
    return change


def _drop(k):
    return lambda meta: meta.pop(k)


DAMAGED = {
    # not authenticated (rejected before anything is parsed)
    "empty file": _raw(lambda p, k, d: b""),
    "binary junk": _raw(lambda p, k, d: bytes(range(256)) * 4),
    "truncated": _raw(lambda p, k, d: signed(k, p.name, json.dumps(d).encode())[:300]),
    "old format (bare JSON)": _raw(lambda p, k, d: json.dumps(d).encode()),
    "force doubled after signing": _raw(
        lambda p, k, d: signed(k, p.name, json.dumps(d).encode()).replace(b"push_u = 10.0", b"push_u = 20.0", 1)),
    "force doubled, MAC with another key": _raw(
        lambda p, k, d: signed(b"\1" * 32, p.name, json.dumps(d).encode().replace(b"push_u = 10.0", b"push_u = 20.0"))),
    "MAC of another file name": _raw(lambda p, k, d: signed(k, "model-0.entry", json.dumps(d).encode())),
    "MAC with another key": _raw(lambda p, k, d: signed(b"\0" * 32, p.name, json.dumps(d).encode())),
    # authenticated with the user's key, but of the wrong shape
    "payload not UTF-8": _raw(lambda p, k, d: signed(k, p.name, b"\xff\xfe{")),
    "payload not JSON": _raw(lambda p, k, d: signed(k, p.name, b"{'source': 1")),
    "JSON a list": _data(lambda d: [d["source"], d["meta"]]),
    "JSON a string": _data(lambda d: d["source"]),
    "JSON null": _data(lambda d: None),
    "source a number": _data(lambda d: {**d, "source": 42}),
    "source a list": _data(lambda d: {**d, "source": d["source"].splitlines()}),
    "source a syntax error": _data(lambda d: {**d, "source": d["source"].replace("def rhs", "def rhs(")}),
    "source without rhs": _data(lambda d: {**d, "source": d["source"].replace("def rhs(", "def rhs_(")}),
    "meta missing": _data(lambda d: {"source": d["source"]}),
    "meta a list": _data(lambda d: {**d, "meta": list(d["meta"])}),
    "meta without name": _meta(_drop("name")),
    "state_names a string": _meta(_set("state_names", "body.p")),
    "x0 too long": _meta(lambda m: m.__setitem__("x0", m["x0"] + [1.0])),
    "x0 empty": _meta(_set("x0", [])),
    "x0 of strings": _meta(lambda m: m.__setitem__("x0", ["0"] * len(m["x0"]))),
    "outputs a dict": _meta(_set("outputs", {"body.v": 1})),
    "units a list": _meta(_set("units", ["m/s"])),
    "unit a number": _meta(lambda m: m.__setitem__("units", {o: 1 for o in m["outputs"]})),
    "aliases odd": _meta(_set("aliases", {"a": "b"})),
}


@pytest.mark.parametrize("name", list(DAMAGED))
def test_a_damaged_entry_is_rebuilt(root, netlist, name):
    simulate(netlist)
    path, key, data = genuine(root)
    planted = DAMAGED[name](path, key, data)
    assert planted != path.read_bytes()
    path.write_bytes(planted)
    assert not simulate(netlist).stats["model_cached"]
    assert simulate(netlist).stats["model_cached"]          # rewritten: the next run restores it


def test_entries_in_the_documented_layout_are_restored(root, netlist):
    """The control for the planted entries: a genuine entry re-signed here is accepted, so the
    planted ones sit where the model is looked up and fail only for what is wrong with them."""
    simulate(netlist)
    path, key, data = genuine(root)
    path.write_bytes(signed(key, path.name, json.dumps(data).encode()))
    assert simulate(netlist).stats["model_cached"]


@pytest.mark.parametrize("kind", ["directory", "fifo", "symlink to /dev/zero", "dangling symlink"])
def test_an_entry_that_is_no_file_is_ignored(root, netlist, kind):
    simulate(netlist)
    path = entry_of(root)
    path.unlink()
    if kind == "directory":
        path.mkdir()
    elif kind == "fifo":
        os.mkfifo(path)
    elif kind == "symlink to /dev/zero":
        path.symlink_to("/dev/zero")
    else:
        path.symlink_to(root / "nothing")
    assert not simulate(netlist).stats["model_cached"]


# -- planted code never runs -------------------------------------------------------------------------

def _planted_source(data, marker: Path) -> str:
    return f"open({str(marker)!r}, 'w').write('ran')\n" + data["source"]


def _plant(root, how: str, marker: Path) -> None:
    path, key, data = genuine(root)
    bad = {**data, "source": _planted_source(data, marker)}
    payload = json.dumps(bad).encode()
    if how == "bare JSON":
        path.write_bytes(payload)
    elif how == "MAC with another key":
        path.write_bytes(signed(os.urandom(32), path.name, payload))
    elif how == "forged MAC":
        path.write_bytes(b"multipole-cache-1 " + b"0" * 64 + b"\n" + payload)
    elif how == "own key in a group-writable folder":
        path.write_bytes(signed(key, path.name, payload))
        root.chmod(0o770)
    elif how == "own key readable by others":
        path.write_bytes(signed(key, path.name, payload))
        (root / "key").chmod(0o644)
    elif how == "control: signed with the user's key":
        path.write_bytes(signed(key, path.name, payload))
    else:
        raise AssertionError(how)


PLANTS = ["bare JSON", "MAC with another key", "forged MAC", "own key in a group-writable folder",
          "own key readable by others"]


def _cli(capsys, *argv):
    pipeline._MODELS.clear()
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("how", PLANTS)
def test_planted_code_never_runs(root, netlist, tmp_path, capsys, monkeypatch, how):
    marker = tmp_path / "marker"
    _cli(capsys, "equations", str(netlist), "--format", "python")      # writes the genuine entry
    _plant(root, how, marker)
    code, out, err = _cli(capsys, "simulate", str(netlist), "--quiet")
    assert code == 0 and not marker.exists()
    code, printed, err = _cli(capsys, "equations", str(netlist), "--format", "python")
    assert code == 0 and not marker.exists()
    assert "marker" not in printed and "def rhs(t, x):" in printed
    monkeypatch.setenv("MULTIPOLE_CACHE", "off")
    assert printed == _cli(capsys, "equations", str(netlist), "--format", "python")[1]
    simulate(netlist)


def test_planted_code_would_run_if_it_were_signed(root, netlist, tmp_path, capsys):
    """The control: the marker the planted source writes is seen when the MAC verifies."""
    marker = tmp_path / "marker"
    _cli(capsys, "equations", str(netlist), "--format", "python")
    _plant(root, "control: signed with the user's key", marker)
    assert _cli(capsys, "equations", str(netlist), "--format", "python")[0] == 0
    assert marker.read_text() == "ran"


# -- private folders and the key ---------------------------------------------------------------------

def _mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


def test_cache_folder_key_and_entries_are_private(root, netlist):
    simulate(netlist)
    assert _mode(root) == 0o700
    assert _mode(root / "key") == 0o600 and len((root / "key").read_bytes()) == 32
    assert _mode(entry_of(root)) & 0o077 == 0
    assert simulate(netlist).stats["model_cached"]


def test_two_users_have_different_keys(tmp_path, monkeypatch, netlist):
    keys = []
    for name in ("a", "b"):
        monkeypatch.setenv("MULTIPOLE_CACHE", str(tmp_path / name))
        pipeline._MODELS.clear()
        simulate(netlist)
        keys.append((tmp_path / name / "key").read_bytes())
    assert keys[0] != keys[1]


def _refused(root, capfd, netlist, words):
    res = simulate(netlist)
    res = simulate(netlist)                   # a second run: still no cache and no second warning
    assert not res.stats["model_cached"]
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(root) in err[0] and words in err[0], err
    assert not list(root.glob("model-*"))


@pytest.mark.parametrize("mode, words", [(0o777, "writable by group and others"), (0o775, "writable by group"),
                                         (0o707, "writable by others")])
def test_a_folder_others_can_write_is_refused(root, netlist, capfd, mode, words):
    root.mkdir()
    root.chmod(mode)
    _refused(root, capfd, netlist, words)
    assert not (root / "key").exists()


def test_a_folder_of_another_user_is_refused(root, netlist, capfd, monkeypatch):
    root.mkdir(mode=0o700)
    monkeypatch.setattr(os, "getuid", lambda uid=os.getuid(): uid + 1)
    _refused(root, capfd, netlist, "not used (owned by uid")


def test_a_file_in_place_of_the_folder_is_refused(root, netlist, capfd):
    root.write_text("")
    _refused(root, capfd, netlist, "")


@pytest.mark.parametrize("spoil, words", [
    (lambda key: key.chmod(0o644), "mode 644"),
    (lambda key: key.write_bytes(b"short"), "5 bytes instead of 32"),
    (lambda key: (key.unlink(), key.symlink_to("/dev/zero")), "cannot read"),
    (lambda key: (key.unlink(), key.mkdir()), "not a regular file"),
])
def test_a_bad_key_file_is_refused(root, netlist, capfd, spoil, words):
    root.mkdir(mode=0o700)
    (root / "key").write_bytes(os.urandom(32))
    (root / "key").chmod(0o600)
    spoil(root / "key")
    _refused(root, capfd, netlist, words)


def test_a_key_file_of_another_user_is_refused(root, netlist, capfd, monkeypatch):
    root.mkdir(mode=0o700)
    (root / "key").write_bytes(os.urandom(32))
    (root / "key").chmod(0o600)
    real = os.fstat           # the folder is checked with os.stat, the opened key with os.fstat
    monkeypatch.setattr(os, "fstat", lambda fd: _owned_by(real(fd), 1))
    _refused(root, capfd, netlist, "key file key: owned by uid")


def _owned_by(st, delta):
    fields = list(st)
    fields[stat.ST_UID] += delta
    return os.stat_result(fields)


# -- the numba cache ---------------------------------------------------------------------------------

numba_backend = pytest.importorskip("multipole.backends.numba_backend")


def test_numba_cache_dir_is_checked(root, capfd):
    assert numba_backend.cache_dir() == root / "numba" and _mode(root / "numba") == 0o700
    (root / "numba").chmod(0o777)
    folder = numba_backend.cache_dir()
    assert folder != root / "numba" and _mode(folder) == 0o700 and folder.stat().st_uid == os.getuid()
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(root / "numba") in err[0]


def test_numba_cache_dir_when_off_is_a_private_folder_of_the_process(monkeypatch):
    monkeypatch.setenv("MULTIPOLE_CACHE", "off")
    folder = numba_backend.cache_dir()
    assert _mode(folder) == 0o700 and folder.stat().st_uid == os.getuid()
    assert folder.name != f"multipole-numba-{os.getuid()}" and folder.name.startswith("multipole-")


def test_numba_keeps_its_cache_in_the_checked_folder(root, tmp_path, monkeypatch):
    """numba picks the folder of its pickled index when a function is decorated; with
    NUMBA_CACHE_DIR pointing elsewhere it must still be the folder cache_dir() checked."""
    from numba.core import config
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.setattr(config, "CACHE_DIR", str(elsewhere))
    module = numba_backend.load(textwrap.dedent(f"""
        from numba import njit

        @njit(cache=True)
        def twice(x):
            return 2.0 * x  # {os.urandom(8).hex()}
        """))
    assert module.twice(3.0) == 6.0
    where = Path(module.twice._cache._cache_path)
    assert where.is_relative_to(root / "numba") and list(where.glob("*.nbi"))
    assert not any(elsewhere.iterdir())
    assert config.CACHE_DIR == str(elsewhere)


# -- deterministic generated code --------------------------------------------------------------------

SCENES = ["drive_train.yaml", "hard/nonlinear_loop.yaml", "weber/spur_ideal.yaml", "hard/stick_slip.yaml",
          "weber/planetary_stepped.yaml", "rlc_series.yaml"]
_DUMP = """
import contextlib, io, sys
from multipole.cli import main
for f in sys.argv[1:]:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["equations", f, "--format", "python"])
    print(f"== {f} exit {code}")
    print(buf.getvalue())
"""


def test_generated_python_does_not_depend_on_the_hash_seed():
    """nonlinear_loop has a Newton loop, spur_ideal a storage in derivative causality (a linear
    loop), stick_slip switches; each seed is a fresh process running the CLI."""
    files = [str(ROOT / "diagrams" / s) for s in SCENES]
    procs = [subprocess.Popen([sys.executable, "-c", _DUMP, *files], stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONHASHSEED": seed, "MULTIPOLE_CACHE": "off"})
             for seed in ("1", "2", "3")]
    outs = [p.communicate(timeout=600)[0] for p in procs]
    assert all(p.returncode == 0 for p in procs)
    assert outs[0].count(" exit 0\n") == len(SCENES) and "_newton" in outs[0]
    assert outs[0] == outs[1] == outs[2]
