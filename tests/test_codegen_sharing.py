"""The generated Python functions share work that Python's interpreter would repeat: the sine and
cosine of each named angle computed once, constants (a constant source, a port held at zero) printed
as numbers with their assignments dropped.  The values must be those of the plain code: checked
against the four-bar's circle intersection and against the numba backend's code, which is printed
without the shared sines and the dropped assignments (its compiler does both)."""
import math

import numpy as np

import multipole as mp
from multipole import codegen, pipeline

L, L1, L2, BX = 0.2, 0.6, 0.5, 0.7

SCENE = f"""
name: fourbar_torque
elements:
  src: {{type: torque_source, value: 0.8}}
  crank: {{type: DAN, l: {L}, phi0: 0.3, m: 1.0, J: 0.01}}
  rocker: {{type: DDD, l1: {L1}, l2: {L2}, K: 1, m1: 2.0, J1: 0.06, m2: 1.5, J2: 0.03, x2: {BX}}}
connections:
  - [src.p, crank.drive]
  - [crank.b, rocker.a1]
outputs: [crank.phi]
simulate: {{t_end: 0.1, dt_out: 0.01}}
"""


def _function(source: str, name: str) -> list:
    lines = source.splitlines()
    start = lines.index(next(line for line in lines if line.startswith(f"def {name}(")))
    end = next(i for i in range(start + 1, len(lines)) if lines[i].startswith("def "))
    return lines[start:end]


def _top_level(body: list) -> list:
    """The statements of a function outside its nested functions (a loop's residual)."""
    out, nested = [], False
    for line in body[1:]:
        top = line.startswith("    ") and not line.startswith("     ")
        nested = line.startswith("    def ") or (nested and not top)
        if top and not nested:
            out.append(line)
    return out


def test_each_angle_has_one_sine_and_one_cosine_in_the_python_rhs():
    """The crank's sine and cosine are computed once; the dyad's angles come from its closure's
    formula, which gives their cosines and sines (assigned once, no trigonometric call)."""
    model = pipeline.model(mp.loads(SCENE, "fourbar.yaml"))
    body = _top_level(_function(model.source, "rhs"))
    text = "\n".join(body)
    for fn in ("sin", "cos"):
        assert text.count(f"math.{fn}(x0)") == 1, fn
        for angle in ("rocker_L1_K_q3", "rocker_L2_K_q3"):
            assert f"math.{fn}({angle})" not in text, (fn, angle)
            assert sum(line.startswith(f"    _{fn}_{angle} = ") for line in body) == 1, (fn, angle)
    assert "src_u =" not in text            # the constant torque is printed as its number
    assert "src_u =" in "\n".join(_function(model.source, "values"))   # values() still reports it


def test_shared_code_gives_the_closure_and_the_plain_values():
    """The closure of the angles holds (circle intersection, Newton tol 1e-12), and the rhs and
    Jacobian equal those of the numba backend's code (rounding: the two print the same sums in other
    orders; the Jacobian's entries divide by the closure's determinant)."""
    sc = mp.loads(SCENE, "fourbar.yaml")
    model = pipeline.model(sc)
    x = np.array(model.x0, dtype=float)
    x[0] += 1e-3
    x[1] = 0.05
    names = model.value_names
    v = dict(zip(names, model.values(0.0, x)))
    th, p1, p2 = x[0], v["rocker.L1.K.q3*"], v["rocker.L2.K.q3*"]
    assert abs(L * math.cos(th) + L1 * math.cos(p1) - L2 * math.cos(p2) - BX) < 1e-11
    assert abs(L * math.sin(th) + L1 * math.sin(p1) - L2 * math.sin(p2)) < 1e-11
    from multipole.backends import numba_backend
    eq, outs, _ = pipeline.pruned(sc)
    compiled = numba_backend.run.compile(eq, outs)
    rhs = compiled._call(compiled.module.rhs, 0.0, x, (len(x),), compiled.w0.copy())
    np.testing.assert_allclose(model.rhs(0.0, x), rhs, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(model.jac(0.0, x), compiled.jac(0.0, x), rtol=1e-8, atol=1e-10)


def test_dead_assignments_are_dropped_and_what_they_read_with_them():
    body = ["    a = 0.8", "    b = -a", "    c = 2.0*x0", "    _g[0] = [c]",
            "    z, = newton(_blk0, _g, 0, _stats)", "    return np.array([c])"]
    assert codegen._live(body) == ["    c = 2.0*x0", "    _g[0] = [c]",
                                   "    z, = newton(_blk0, _g, 0, _stats)", "    return np.array([c])"]


def test_a_constant_source_given_as_a_symbolic_number_is_folded():
    """A force source of ``62*pi`` N (a number sympy keeps symbolic) on a 2 kg mass from rest: the
    folded constant gives v = F t/m (it used to stop the code generation with a TypeError)."""
    scene = mp.loads("""
name: pushed
elements:
  src: {type: force_source, value: 62*pi}
  body: {type: mass, m: 2.0}
connections:
  - [src.p, body.a]
outputs: [body.v]
simulate: {t_end: 0.5, dt_out: 0.1, rtol: 1.0e-10}
""")
    result = pipeline.run(scene, progress=False)
    assert np.allclose(result["body.v"], 62 * math.pi * result.t / 2.0, rtol=1e-12, atol=1e-12)
