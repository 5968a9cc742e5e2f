"""A warm ``pipeline.run`` derives nothing again: counted work, not time (issue 11).

The numba backend compiles from the derived equations; a second run of the same scene in the same
process must neither assemble the equations (sympy) nor translate them to source again, and must
still give the closed-form answer (series RLC step response).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from multipole import pipeline
from multipole.netlist import load

RLC = Path(__file__).resolve().parents[1] / "diagrams" / "rlc_series.yaml"
V, R, L, C = 12.0, 10.0, 0.1, 1.0e-4


def rlc_vc(t):
    """Capacitor voltage of the series RLC after a V step at t = 0 (underdamped closed form) [V]."""
    a = R / (2 * L)
    wd = math.sqrt(1 / (L * C) - a * a)
    return V * (1 - np.exp(-a * t) * (np.cos(wd * t) + a / wd * np.sin(wd * t)))


@pytest.fixture
def counted(monkeypatch, tmp_path):
    """Counters of equation assemblies and of numba translations, with the in-process memo and the
    disk cache empty (a numba model restored from the disk cache derives nothing at all)."""
    from multipole.backends import numba_backend
    monkeypatch.setenv("MULTIPOLE_CACHE", str(tmp_path / "cache"))
    calls = {"assemble": 0, "translate": 0}

    def counting(name, fun):
        def wrapper(*args, **kwargs):
            calls[name] += 1
            return fun(*args, **kwargs)
        return wrapper

    monkeypatch.setattr(pipeline, "assemble", counting("assemble", pipeline.assemble))
    monkeypatch.setattr(numba_backend, "translate", counting("translate", numba_backend.translate))
    monkeypatch.setattr(pipeline, "_PRUNED", {})
    monkeypatch.setattr(pipeline, "_CHECKED", {})      # an earlier check's analysis holds assembled equations
    return calls


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_warm_run_derives_nothing(counted, backend):
    pytest.importorskip("numba")
    scene = load(RLC)
    first = pipeline.run(scene, backend=backend, rtol=1e-10, atol=1e-12)
    assembled, translated = counted["assemble"], counted["translate"]
    assert assembled >= 1 or backend == "numpy"           # numpy may restore its model from the disk cache
    again = pipeline.run(load(RLC), backend=backend, rtol=1e-10, atol=1e-12)   # a new Scene, same text
    assert counted["assemble"] == assembled
    assert counted["translate"] == translated
    for result in (first, again):
        vc = result.outputs["C1.v"]
        # rtol 1e-10 on a 12 V signal: the global error stays far below 1e-6 V
        assert np.max(np.abs(vc - rlc_vc(result.t))) < 1e-6


def test_memo_is_bounded(counted, monkeypatch):
    """A sweep over many overrides keeps at most MAX_PRUNED derivations in memory."""
    monkeypatch.setattr(pipeline, "MAX_PRUNED", 2)
    for value in (10.0, 11.0, 12.0):
        pipeline.pruned(load(RLC, overrides={"V": value}))
    assert len(pipeline._PRUNED) == 2
    assert counted["assemble"] == 3
