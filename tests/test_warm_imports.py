"""What a warm ``multipole simulate`` process imports (issue 11: "a warm numba call no slower than a
warm numpy call"; docs/performance.md, "A new process on the numba backend").

Every library a process imports costs CPU time twice, at import and at interpreter exit, so a warm
run imports only what it uses: ``import multipole`` loads no scipy; a run on the numba backend
loads none of scipy's integrators or optimisers (numba itself loads ``scipy.linalg``); no run
loads matplotlib or pandas unless it plots or writes a data frame.  Each case runs in a new
process (``sys.modules`` of this one holds whatever other tests imported).  No time is measured.

The stability polynomials ``auto`` uses without scipy are checked against the ones computed from
scipy's own Butcher tableaus.  A command's process skips the garbage collector's passes at exit
(``multipole.cli._no_collection_at_exit``): its files are still complete and its temporary folders
still removed.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from test_cache_trust import D, DRAG, F, M

#: prints the modules loaded by ``multipole simulate ARGS...`` as JSON on the last line of stdout
PROBE = ("import json, sys\nfrom multipole.cli import main\ncode = main(sys.argv[1:])\n"
         "print(json.dumps({'code': code, 'modules': sorted(sys.modules)}))")
#: what neither backend's warm run needs (nothing is plotted, no data frame is made)
NEVER = ("matplotlib", "pandas")
#: what only the numpy backend's integrators need (``scipy.integrate`` imports the others)
SCIPY_INTEGRATORS = ("scipy.integrate", "scipy.optimize", "scipy.interpolate", "scipy.sparse", "scipy.special")


def loaded(*args, cache) -> tuple[list, str]:
    """``(modules, stdout)`` of ``multipole simulate ARGS...`` in a new process with model cache ``cache``."""
    env = dict(os.environ, MULTIPOLE_CACHE=str(cache))
    out = subprocess.run([sys.executable, "-c", PROBE, "simulate", *map(str, args)], env=env,
                         capture_output=True, text=True, check=True)
    report = json.loads(out.stdout.splitlines()[-1])
    assert report["code"] == 0, out.stderr
    return report["modules"], out.stdout


def final_velocity(stdout: str) -> float:
    """``body.v`` from the ``final values:`` line."""
    line = next(s for s in stdout.splitlines() if s.startswith("final values:"))
    return float(line.split("body.v = ")[1].split(",")[0])


def present(modules, names) -> list:
    return [m for m in names if m in modules]


def test_import_multipole_loads_no_scipy():
    out = subprocess.run([sys.executable, "-c", "import json, sys, multipole; print(json.dumps(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True)
    modules = json.loads(out.stdout)
    assert "multipole.pipeline" in modules            # the probe did import the package
    assert [m for m in modules if m == "scipy" or m.startswith("scipy.")] == []
    assert present(modules, NEVER) == []


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_warm_run_imports_only_what_it_uses(backend, tmp_path):
    if backend == "numba":
        pytest.importorskip("numba")
    netlist = tmp_path / "drag.yaml"
    netlist.write_text(DRAG)
    cold, _ = loaded(netlist, "--quiet", "--backend", backend, cache=tmp_path / "cache")
    warm, stdout = loaded(netlist, "--quiet", "--backend", backend, cache=tmp_path / "cache")
    # the warm run did the work: v(1 s) of the closed form v = F/d (1 - exp(-d t/m)), rtol 1e-10;
    # the line prints 6 significant digits
    assert final_velocity(stdout) == pytest.approx(F / D * (1 - math.exp(-D / M)), rel=1e-5)
    assert "model from cache" in stdout
    assert present(warm, NEVER) == []
    if backend == "numba":
        assert "numba" in warm
        assert present(warm, SCIPY_INTEGRATORS) == []
    else:
        assert "scipy.integrate" in warm              # the probe can see them: the numpy run uses them


@pytest.mark.parametrize("method", ["RK45", "DOP853"])
def test_stability_polynomials_match_scipys_tableaus(method):
    from multipole.simulate import _STABILITY_POLYNOMIALS, _tableau_polynomial
    table = np.array(_STABILITY_POLYNOMIALS[method])
    tableau = _tableau_polynomial(method)
    assert table.shape == tableau.shape
    # coefficients down to 3.6e-10 (z^12 of DOP853), each to the rounding of scipy's sums
    np.testing.assert_allclose(table, tableau, rtol=1e-12, atol=0)
    # up to the method's order they are those of exp(z): 1/k!
    order = {"RK45": 5, "DOP853": 8}[method]
    expected = [1 / math.factorial(k) for k in range(order, -1, -1)]
    np.testing.assert_allclose(table[-order - 1:], expected, rtol=1e-12)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_exit_keeps_files_and_clean_up(backend, tmp_path):
    """Without a disk cache the numba backend keeps its generated module in a private folder of
    the process (``multipole.cache.process_dir``), removed by an atexit handler: still removed; the
    CSV the command wrote is whole (every row of the grid, the last one the closed form)."""
    if backend == "numba":
        pytest.importorskip("numba")
    netlist, out, temp = tmp_path / "drag.yaml", tmp_path / "v.csv", tmp_path / "tmp"
    netlist.write_text(DRAG)
    temp.mkdir()
    env = dict(os.environ, MULTIPOLE_CACHE="off", TMPDIR=str(temp))
    subprocess.run([sys.executable, "-m", "multipole.cli", "simulate", str(netlist), "--quiet", "--backend", backend,
                    "--out", str(out)], env=env, cwd=tmp_path, check=True, capture_output=True)
    rows = out.read_text().splitlines()
    assert rows[0].split(",") == ["t [s]", "body.v [m/s]"]
    assert len(rows) == 1 + 101                       # t = 0, 0.01, ..., 1 s
    t, v = map(float, rows[-1].split(","))
    assert t == 1.0
    assert v == pytest.approx(F / D * (1 - math.exp(-D / M)), rel=1e-8)
    assert list(temp.iterdir()) == []                 # the process folder was removed at exit


def test_only_the_process_command_freezes_objects():
    """``main()`` reading ``sys.argv`` (the process's command) freezes what the imports made;
    ``main(argv)`` called in a process (a test, a script) leaves its collection alone."""
    import gc
    from multipole.cli import main
    frozen = gc.get_freeze_count()
    assert main(["elements", "mass"]) == 0
    assert gc.get_freeze_count() == frozen
    probe = ("import gc, sys\nfrom multipole.cli import main\nsys.argv = ['multipole', 'elements', 'mass']\n"
             "before = gc.get_freeze_count()\ncode = main()\nprint(code, before, gc.get_freeze_count())")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    code, before, after = map(int, out.stdout.split()[-3:])
    assert code == 0 and before == 0
    assert after > 10_000                 # numpy, sympy and the kernel's modules are in there
