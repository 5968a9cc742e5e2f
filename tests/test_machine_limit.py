"""The machine-limit loop of benchmarks/machine_limit.py integrates the same equations as the
generated model: its hand-written scalar cfuncs (right-hand side, Jacobian, outputs) equal the
generated ones and the bench's hand-written numpy models at random states, to rounding."""
import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

import multipole as mp
from multipole import bench, pipeline

numba = pytest.importorskip("numba")
from multipole.backends import numba_backend  # noqa: E402  (needs numba)

ROOT = Path(__file__).resolve().parents[1]
EPS = np.finfo(float).eps


def _limit_module():
    spec = importlib.util.spec_from_file_location("machine_limit_under_test", ROOT / "benchmarks" / "machine_limit.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


ML = _limit_module()


def _call(fun, t, x, shape, n_work):
    out = np.zeros(shape)
    x = np.ascontiguousarray(x, dtype=float)
    fun.ctypes(float(t), x.ctypes.data, out.ctypes.data, np.zeros(n_work).ctypes.data)
    return out


@pytest.fixture(scope="module", params=list(ML.SCENES))
def models(request):
    """(scene, generated numba module, hand-written cfunc module, bench's numpy hand model)."""
    sc = mp.load(ROOT / ML.SCENES[request.param])
    eq, outs = pipeline.equations(sc), list(sc.outputs)
    generated = numba_backend.run.compile(eq, outs)
    mine, names = ML.hand_module(sc)
    hand = bench.hand_model(sc)
    assert list(generated.state_names) == names == list(hand.state_names)
    return sc, generated.module, mine, hand


def _states(sc, hand, rng, k=25):
    """Random times [s] and states spanning what the runs visit (speeds up to 200 rad/s, shaft twists
    up to 0.05 rad, crank angles over several turns)."""
    t_end = float(sc.simulate["t_end"])
    out = []
    for _ in range(k):
        if sc.reference["hand_model"] == "slider_crank":
            J = hand.x0[0] / 60.0                      # flywheel.p = J * w0 with w0 = 60 rad/s
            x = np.array([J * rng.uniform(-200, 200), rng.uniform(-20, 20)])
        else:
            J1, J2 = 1.0 / hand.A[1, 0], -1.0 / hand.A[1, 2]          # q' = p1/(i J1) - p2/J2
            x = np.array([J1 * rng.uniform(-200, 200), rng.uniform(-0.05, 0.05), J2 * rng.uniform(-200, 200)])
        out.append((rng.uniform(0, t_end), x))
    return out


def _scale(sc, hand, t, x):
    """Sum of the magnitudes of the terms of each derivative (a bound of its rounding error in units
    of eps times the number of operations): |A| |x| plus the motor torque for the drive trains; for
    the slider crank |J x'| (F0 + m |x''| w²)/(J + m x'²) and |w|, from the kinematics of the hand model."""
    if hand.A is not None:
        return np.abs(hand.A) @ np.abs(x) + np.abs(hand.forcing(t))
    p = ML._params(sc, ML.mm._CRANK)
    J, m, F0 = p["J"], p["m"], p["F0"]
    w = x[0] / J
    d1, d2, _ = ML.mm._crank_kinematics(x[1], p["r"], p["l"])
    return np.array([abs(J * d1) * (F0 + m * abs(d2) * w * w) / (J + m * d1 * d1), abs(w)])


# the generated slider-crank derivative is an expanded polynomial: a sum of about 30 rounded products
# of powers of sin, cos and a square root (the drive trains: a few products), each off by about 1 eps
# of its size; 64 eps of the scale bounds the sum (measured: at most 4 eps over 200 random states)
ROUNDING = 64 * EPS
# its Jacobian entries sum about 100 such products, relative to an entry that may cancel down by a
# factor of ten: 1e3 eps (measured: at most 40 eps over 200 random states)
JAC_ROUNDING = 1e3 * EPS


def test_hand_rhs_equals_the_generated_rhs_and_the_numpy_hand_model(models):
    sc, gen, mine, hand = models
    n = len(hand.x0)
    for t, x in _states(sc, hand, np.random.default_rng(11)):
        expected = _call(mine.rhs, t, x, n, mine.N_WORK)
        tol = ROUNDING * _scale(sc, hand, t, x)
        assert np.all(np.abs(_call(gen.rhs, t, x, n, gen.N_WORK) - expected) <= tol), (t, x)
        assert np.all(np.abs(np.asarray(hand.rhs(t, x)) - expected) <= tol), (t, x)


def test_hand_jacobian_equals_the_generated_one_and_a_difference_quotient(models):
    sc, gen, mine, hand = models
    n = len(hand.x0)
    for t, x in _states(sc, hand, np.random.default_rng(12), k=10):
        expected = _call(mine.jac, t, x, (n, n), mine.N_WORK)
        assert np.allclose(_call(gen.jac, t, x, (n, n), gen.N_WORK), expected, rtol=JAC_ROUNDING, atol=0.0), (t, x)
        assert np.allclose(np.asarray(hand.jac(t, x)), expected, rtol=JAC_ROUNDING, atol=0.0), (t, x)
        # central difference of the hand-written right-hand side: truncation ~ h^2, rounding ~ eps/h
        for j in range(n):
            h = 1e-5 * max(abs(x[j]), 1e-3)
            up, down = x.copy(), x.copy()
            up[j] += h
            down[j] -= h
            col = (_call(mine.rhs, t, up, n, 3) - _call(mine.rhs, t, down, n, 3)) / (2 * h)
            scale = _scale(sc, hand, t, x) / max(abs(x[j]), 1e-3)
            assert np.all(np.abs(col - expected[:, j]) <= 1e-6 * scale + 1e-6 * np.abs(expected[:, j])), (t, x, j)


def test_hand_outputs_equal_the_generated_outputs(models):
    sc, gen, mine, hand = models
    n_out = len(sc.outputs)
    for t, x in _states(sc, hand, np.random.default_rng(13), k=10):
        expected = _call(mine.outputs, t, x, n_out, mine.N_WORK)
        got = _call(gen.outputs, t, x, n_out, gen.N_WORK)
        assert np.allclose(got, expected, rtol=ROUNDING, atol=0.0), (t, x)
        numpy_hand = {name: float(np.ravel(g(t, x.reshape(-1, 1)))[0]) for name, g in hand.outputs.items()}
        for k, name in enumerate(sc.outputs):
            if name in numpy_hand:
                assert math.isclose(numpy_hand[name], expected[k], rel_tol=ROUNDING), name


def test_limit_loop_reaches_the_closed_form_and_does_the_work_of_the_generated_model():
    """The bare loop with the hand-written stiff drive train: Radau at rtol 1e-8 within 1e-6 of the
    closed form of load.omega, with the generated model's work counts to within a few per cent (same
    method, same equations; rounding may move a step)."""
    sc = mp.load(ROOT / ML.SCENES["stiff_drive_train"])
    model = pipeline.model(sc)
    ref = bench.build_reference(sc, model)
    grid = ML.output_grid(ref.t_end, ref.dt_out)
    outs = list(sc.outputs)
    mine, _ = ML.hand_module(sc)
    hand = bench.hand_model(sc)
    res = ML.BareLoop(mine, hand.x0, grid, ref.t_end, outs)("Radau", 1e-8, 1e-11)
    err = np.max(np.abs(res["load.omega"] - ref.at(grid))) / ref.scale
    assert err < 1e-6
    gen = numba_backend.run(pipeline.equations(sc), outs, ref.t_end, ref.dt_out, "Radau", 1e-8, 1e-11, math.inf, False)
    for key in ("nfev", "njev", "nlu", "steps"):
        assert abs(res.stats[key] - gen.stats[key]) <= 0.05 * gen.stats[key] + 2, key
