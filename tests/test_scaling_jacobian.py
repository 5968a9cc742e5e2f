"""The sparse Jacobian of large models (docs/performance.md §3): ``jac_sparse`` is the same matrix as
the derivative of the right-hand side, and only Radau and BDF are handed it (LSODA and GL4 take a
dense array)."""
from pathlib import Path

import numpy as np
import pytest
from scipy.sparse import issparse

import multipole_models
from multipole import codegen, pipeline
from multipole.simulate import IMPLICIT, SOLVERS, jacobian_for, simulate
from multipole.netlist import load, loads

ROOT = Path(__file__).resolve().parents[1]
#: small models with each kind of step of the Jacobian plan: plain assignments of a non-affine law
#: (cubic springs), a nonlinear algebraic loop, derivative causality, switches (``jac_in_mode``)
MODELS = {
    "cubic_chain": lambda: loads(multipole_models.mass_spring_chain(3, c3=1e6), "cubic_chain.yaml"),
    "nonlinear_loop": lambda: load(ROOT / "diagrams/hard/nonlinear_loop.yaml"),
    "slider_crank": lambda: load(ROOT / "diagrams/hard/slider_crank.yaml"),
    "stick_slip": lambda: load(ROOT / "diagrams/hard/stick_slip.yaml"),
    "stiff_drive_train": lambda: load(ROOT / "diagrams/hard/stiff_drive_train.yaml"),
}


@pytest.fixture
def sparse_everywhere(monkeypatch):
    """Every model, however small, on the sparse path (its threshold lowered to one state)."""
    monkeypatch.setattr(codegen, "SPARSE_JACOBIAN_STATES", 1)


def _model(key):
    sc = MODELS[key]()
    return codegen.compile_model(pipeline.equations(sc), sc.outputs)


def _differences(fun, t, x):
    """d fun/dx by central differences with Richardson extrapolation, ``(4 D(h/2) - D(h))/3`` with
    h_j = 1e-6·max(1, |x_j|): error O(h⁴) in the scale on which the law bends (stick-slip's friction
    turns over within 1e-5 m/s: central differences alone with h = 6e-6 are 0.4 % off there), and
    round-off about eps·|f|/h, 1e-9 of the entries' scale for these models."""
    n = len(x)

    def central(h):
        J = np.empty((len(fun(t, x)), n))
        for j in range(n):
            e = np.zeros(n)
            e[j] = h * max(1.0, abs(x[j]))
            J[:, j] = (np.asarray(fun(t, x + e)) - np.asarray(fun(t, x - e))) / (2 * e[j])
        return J
    return (4 * central(0.5e-6) - central(1e-6)) / 3


@pytest.mark.parametrize("key", ["cubic_chain", "nonlinear_loop", "slider_crank", "stick_slip"])
def test_sparse_jacobian_equals_differences_of_the_right_hand_side(sparse_everywhere, key):
    model = _model(key)
    assert model.jac_sparse is not None
    rng = np.random.default_rng(7)
    for k in range(3):
        t = 0.013 * k
        x = model.x0 + 0.01 * rng.standard_normal(len(model.x0)) * np.maximum(1.0, np.abs(model.x0))
        if model.n_switches:          # hold every switch on the side it is on at x, as a segment does
            model.set_mode(np.where(np.asarray(model.switches(t, x)) < 0, -1.0, 1.0))
            rhs, jac = model.rhs_in_mode, model.jac_sparse_in_mode
        else:
            rhs, jac = model.rhs, model.jac_sparse
        J = jac(t, x)
        assert J.format == "csc", key
        expected = _differences(rhs, t, x)
        scale = max(1.0, float(np.max(np.abs(expected))))
        assert np.max(np.abs(J.toarray() - expected)) <= 1e-7 * scale, key
        assert np.array_equal(model.jac(t, x), J.toarray())       # the dense view is the same matrix


def test_cubic_chain_sparse_jacobian_equals_the_hand_written_one(sparse_everywhere):
    """The cubic chain against its hand-written Jacobian (dF/dq = c + 3 c3 q², written from the physics)."""
    sc = loads(multipole_models.mass_spring_chain(4, c3=1e6), "cubic_chain.yaml")
    model = codegen.compile_model(pipeline.equations(sc), sc.outputs)
    hand = multipole_models.hand_model(sc)
    idx = hand.permutation(model.state_names)
    x = np.random.default_rng(3).normal(size=8) * 0.05
    J = model.jac_sparse(0.2, x).toarray()[np.ix_(idx, idx)]
    own = hand.jac(0.2, x[idx])
    assert np.max(np.abs(J - own)) <= 4 * np.finfo(float).eps * np.max(np.abs(own))
    assert np.count_nonzero(own) == model.jac_sparse(0.2, x).nnz     # no stored zeros beyond the physics'


def test_small_models_keep_the_dense_jacobian_and_large_ones_get_the_sparse_one():
    small = _model("cubic_chain")                                     # 6 states
    assert len(small.x0) < codegen.SPARSE_JACOBIAN_STATES and small.jac_sparse is None
    sc = loads(multipole_models.mass_spring_chain(codegen.SPARSE_JACOBIAN_STATES // 2, c3=1e6), "c.yaml")
    large = codegen.compile_model(pipeline.equations(sc), sc.outputs)
    assert issparse(large.jac_sparse(0.0, large.x0))
    assert not issparse(large.jac(0.0, large.x0))


def _spy_on_solvers(monkeypatch) -> list:
    """Replace every scipy method of the driver by a subclass that records (method, whether the
    Jacobian it was given returns a sparse matrix)."""
    seen = []
    for name, cls in list(SOLVERS.items()):
        def init(self, fun, t0, y0, *args, _cls=cls, _name=name, **kw):
            jac = kw.get("jac")
            if jac is not None:
                seen.append((_name, issparse(jac(t0, np.asarray(y0, dtype=float)))))
            _cls.__init__(self, fun, t0, y0, *args, **kw)
        monkeypatch.setitem(SOLVERS, name, type(f"Spy{name}", (cls,), {"__init__": init}))
    return seen


def test_only_radau_and_bdf_are_given_a_sparse_jacobian(sparse_everywhere, monkeypatch):
    """LSODA and GL4 get the dense Jacobian, Radau and BDF the sparse one; ``auto`` on a stiff model
    runs Radau with the sparse one (and never LSODA with it)."""
    seen = _spy_on_solvers(monkeypatch)
    model = _model("stiff_drive_train")     # compiled here: pipeline.model's caches ignore the threshold
    for solver in ("LSODA", "GL4", "Radau", "BDF"):
        assert simulate(model, 1e-3, solver=solver, progress=False).solver == solver
    res = simulate(model, 1e-3, solver="auto", progress=False)
    assert res.solver == "Radau" and res.solver_reason.startswith("stiff")
    assert sorted(set(seen)) == [("BDF", True), ("GL4", False), ("LSODA", False), ("Radau", True)], seen
    assert seen[-1] == ("Radau", True)
    for solver in IMPLICIT:
        assert issparse(jacobian_for(model, solver)(0.0, model.x0)) == (solver in ("Radau", "BDF"))
