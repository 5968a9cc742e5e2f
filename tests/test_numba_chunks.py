"""The numba backend compiles a large generated function as chunks of bounded size
(``numba_backend.CHUNK_STATEMENTS``): the same values as the function written in one piece, the
numpy backend's values within rounding, a bounded largest chunk and a number of chunks that grows
linearly with the model (work counters, no times: docs/performance.md, "numba compile time against
model size")."""
from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from helpers import scene  # noqa: E402

import multipole_models  # noqa: E402
from multipole import codegen, pipeline  # noqa: E402
from multipole.netlist import load  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
STACK = ROOT / "diagrams" / "weber" / "piezo_stack.yaml"


@pytest.fixture
def nb():
    pytest.importorskip("numba")
    from multipole.backends import numba_backend
    return numba_backend


def _functions(source: str) -> dict:
    """Top-level function name -> number of statements (source lines of its body, docstring left out)."""
    tree = ast.parse(source)
    return {f.name: f.end_lineno - f.body[1].lineno + 1 for f in tree.body
            if isinstance(f, ast.FunctionDef) and len(f.body) > 1}


def _chunks(source: str, name: str) -> dict:
    return {f: k for f, k in _functions(source).items() if f.startswith(f"_{name}_")}


def _chain(n: int):
    sc = scene(multipole_models.mass_spring_chain(n))
    return pipeline.equations(sc), sc.outputs


def _stack_without_masses(n: int):
    """Piezo stack of ``n`` massless discs: a linear loop of 3n unknowns solved in the work array."""
    text = STACK.read_text(encoding="utf-8").replace("n: 10,", f"n: {n},").replace("m: 5.0e-4,", "m: 0.0,")
    sc = scene(text)
    return pipeline.equations(sc), sc.outputs


def _file(path: str):
    sc = load(ROOT / "diagrams" / path)
    return pipeline.equations(sc), sc.outputs


def _generate(nb, monkeypatch, eq, outputs, limit):
    monkeypatch.setattr(nb, "CHUNK_STATEMENTS", limit)
    return nb.generate(eq, outputs)


#: time of the sampled evaluations [s]: before the piezo stack's voltage ramp ends (5e-4 s), so the
#: switch the numba functions hold on its side at t = 0 is on that side for the numpy backend too
T = 1e-4


def _evaluate(nb, eq, outputs, source, switch_text, states):
    """rhs, jac, outputs and switches at ``T`` of the module compiled from ``source`` at each state."""
    module = nb.load(source)
    model = nb.NumbaModel(eq, outputs, module, switch_text, nb._initial_state(eq), 0.0, 0.0, False)
    n = len(eq.states)
    return [(model._call(module.rhs, T, x, n, model.w0.copy()), model.jac(T, x), model.outputs(T, x),
             model.switches(T, x)) for x in states]


def _states(eq, count=4, seed=7):
    rng = np.random.default_rng(seed)
    x0 = np.array(eq.initial_values(), dtype=float)
    return [x0 + 0.05 * (1.0 + np.abs(x0)) * rng.standard_normal(x0.size) for _ in range(count)]


def _crank_with_gauss(mp):
    """The motor, gear and crank with its 5-unknown linear loop solved by Gaussian elimination in
    views of the work array (``_A``, ``_b``) instead of unrolled scalar elimination."""
    mp.setattr(codegen, "UNROLL_MAX_UNKNOWNS", 2)
    return _file("linkages/motor_gear_crank.yaml")


CASES = {"chain of 12 pairs": lambda mp: _chain(12),
         "piezo stack of 4 massless discs": lambda mp: _stack_without_masses(4),
         "nonlinear loop (Newton)": lambda mp: _file("hard/nonlinear_loop.yaml"),
         "motor, gear and crank (Newton loop, unrolled linear loop)":
             lambda mp: _file("linkages/motor_gear_crank.yaml"),
         "motor, gear and crank (linear loop in w)": _crank_with_gauss,
         "stick-slip (switches held on their side)": lambda mp: _file("hard/stick_slip.yaml")}


@pytest.mark.parametrize("case", list(CASES))
def test_chunked_functions_give_the_values_of_the_whole_function(nb, monkeypatch, case):
    """Cut into chunks of about 6 statements (reordered, values passed through w), every function
    gives bit for bit the values of the same module written as whole functions: each value is the
    same expression of the same operands (no operation is reassociated)."""
    eq, outputs = CASES[case](monkeypatch)
    whole, text = _generate(nb, monkeypatch, eq, outputs, 10**9)
    cut, text_cut = _generate(nb, monkeypatch, eq, outputs, 6)
    assert text_cut == text
    assert not _chunks(whole, "rhs") and not _chunks(whole, "jac")
    assert len(_chunks(cut, "rhs")) >= 2 and len(_chunks(cut, "jac")) >= 2, _functions(cut)
    states = _states(eq)
    for a, b in zip(_evaluate(nb, eq, outputs, whole, text, states), _evaluate(nb, eq, outputs, cut, text, states)):
        for u, v in zip(a, b):
            assert np.array_equal(u, v, equal_nan=True)


@pytest.mark.parametrize("case", ["chain of 12 pairs", "motor, gear and crank (linear loop in w)"])
def test_chunked_functions_match_the_numpy_backend(nb, monkeypatch, case):
    """The chunked right-hand side, Jacobian and outputs against the numpy backend's generated
    Python at sampled states: the same formulas evaluated in another order of operations (numpy's
    linear solves, sympy's printing), so they agree to a few hundred units of rounding of the
    largest term, 1e-12 relative (a Newton loop is solved to 1e-12 relative by both)."""
    eq, outputs = CASES[case](monkeypatch)
    source, text = _generate(nb, monkeypatch, eq, outputs, 12)
    reference = codegen.compile_model(eq, outputs)
    states = _states(eq)
    for x, (f, J, y, _g) in zip(states, _evaluate(nb, eq, outputs, source, text, states)):
        for got, want in ((f, reference.rhs(T, x)), (J, reference.jac(T, x)), (y, reference.outputs(T, x))):
            want = np.asarray(want, dtype=float)
            scale = max(1.0, float(np.abs(want).max(initial=0.0)))
            assert np.allclose(got, want, rtol=1e-10, atol=1e-10 * scale), (case, got, want)


def test_a_small_function_is_written_whole(nb):
    """Below the limit the module is what it was before chunking: no chunk functions, nothing passed
    through the work array (the bench scenes run the code they ran)."""
    eq, outputs = _file("hard/slider_crank.yaml")
    source, _ = nb.generate(eq, outputs)
    assert not any(name.startswith(("_rhs_", "_jac_", "_outputs_", "_switches_")) for name in _functions(source))


def test_chunks_are_bounded_and_grow_linearly_with_the_chain(nb):
    """Work counters of the chunking on chains of 50, 100 and 200 pairs: no chunk is longer than the
    limit plus one statement, the number of chunks of rhs and jac grows in proportion to the pairs
    (within 20 %), and the values passed between chunks stay few (a chain is local: the
    depth-first order computes each output's operands together)."""
    limit = nb.CHUNK_STATEMENTS
    counts = {}
    for n in (50, 100, 200):
        source, _ = nb.translate(*_chain(n))
        functions = _functions(source)
        for name in ("rhs", "jac"):
            chunks = _chunks(source, name)
            assert chunks, (n, name)
            # a chunk's own statements, then what it reads from w and writes back: bounded too
            assert max(chunks.values()) <= limit + 1 + 16, (n, name, chunks)
            counts[n, name] = len(chunks)
        assert functions["rhs"] <= 3 + counts[n, "rhs"]      # the cfunc only calls its chunks
        # values read back from w: a few per chunk, not one per statement
        assert source.count(" = w[") <= 8 * (counts[n, "rhs"] + counts[n, "jac"]), (n, source.count(" = w["))
    for name in ("rhs", "jac"):
        per_pair = [counts[n, name] / n for n in (50, 100, 200)]
        assert max(per_pair) <= 1.2 * min(per_pair) + 1 / 50, (name, counts)
    assert counts[200, "rhs"] >= 3 * counts[50, "rhs"] - 1


def test_a_loop_matrix_is_never_cut(nb, monkeypatch):
    """A linear loop's matrix, its right-hand side and its solve (views of w) stay in one chunk,
    however small the limit: every chunk that stores into ``_A`` also defines and solves it."""
    eq, outputs = _crank_with_gauss(monkeypatch)
    source, _ = _generate(nb, monkeypatch, eq, outputs, 3)
    tree = ast.parse(source)
    chunks = [f for f in tree.body if isinstance(f, ast.FunctionDef) and f.name.startswith(("_rhs_", "_jac_"))]
    using = [ast.unparse(f) for f in chunks if "_A[" in ast.unparse(f)]
    assert using
    for text in using:
        assert "_A = w[" in text and "gauss_solve(_A, _b)" in text


def test_the_size_limits_bound_the_compile_time(nb, monkeypatch):
    """In chunks, numba's compile time grows linearly with the source cost: the default limits admit the
    300-pair chain (600 states).  Written whole, the 150-pair chain's Jacobian alone is above the limit
    of one function (LLVM's time in one function is super-linear), and a limit on the whole source
    below the 300-pair chain's cost refuses it; both messages name the cost and the variable."""
    eq, outputs = _chain(300)
    source = nb.translate(eq, outputs)[0]
    nb.check_size(source)
    assert max(nb.function_costs(source).values()) <= nb.MAX_FUNCTION_COST
    monkeypatch.setenv("MULTIPOLE_NUMBA_MAX_COST", "100000")
    with pytest.raises(nb.ModelTooLarge) as exc:
        nb.check_size(source)
    assert exc.value.what == "too large" and "above the limit of 100,000" in exc.value.reason
    assert "MULTIPOLE_NUMBA_MAX_COST" in exc.value.fix
    monkeypatch.delenv("MULTIPOLE_NUMBA_MAX_COST")
    whole, _ = _generate(nb, monkeypatch, *_chain(150), 10**9)
    with pytest.raises(nb.ModelTooLarge) as exc:
        nb.check_size(whole)
    assert exc.value.reason.startswith("its generated function jac costs ")
    assert f"above the limit of {nb.MAX_FUNCTION_COST:,} for one function" in exc.value.reason
    assert "MULTIPOLE_NUMBA_MAX_FUNCTION_COST" in exc.value.fix


def test_a_chunked_model_is_the_same_source_and_a_cache_hit_in_another_process(nb, tmp_path):
    """The chunked source does not depend on Python's hash seed (it is the cache key), and a second
    process loads its cfuncs, chunks linked in, from numba's cache without compiling them."""
    code = ("import hashlib, multipole_models; from multipole import pipeline; from multipole.netlist import loads;"
            "from multipole.backends import numba_backend as nb; nb.CHUNK_STATEMENTS = 20;"
            "sc = loads(multipole_models.mass_spring_chain(12), 'chain.yaml');"
            "source = nb.generate(pipeline.equations(sc), sc.outputs)[0]; m = nb.load(source);"
            "print(hashlib.sha256(source.encode()).hexdigest(), source.count('def _rhs_'),"
            " m.rhs.cache_hits, m.jac.cache_hits)")
    env = {**os.environ, "MULTIPOLE_CACHE": str(tmp_path)}
    first, second = (subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                                    env={**env, "PYTHONHASHSEED": seed}).stdout.split() for seed in ("1", "2"))
    assert first[0] == second[0] and int(first[1]) >= 2
    assert first[2:] == ["0", "0"] and second[2:] == ["1", "1"]
