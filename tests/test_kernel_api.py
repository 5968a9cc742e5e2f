"""Kernel API pieces used by element libraries: signals from taps, nested networks, MTF, CField."""
import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

from multipole import (C, CField, I, MTF, LAW_Q, Network, Se, Sf, T, Tap, analyse, assemble, compile_model,
                       flatten, junction_a, junction_b, simulate)


def _model(net, outputs):
    an = analyse(flatten(net))
    assert an.ok, an.report()
    return compile_model(assemble(an), outputs)


def test_stiffness_modulated_by_a_tapped_angle():
    """A spring whose stiffness depends on the angle of the body driving it (via a Tap signal)."""
    J, c0, eps, z, T0 = 0.01, 50.0, 0.3, 3.0, 0.2
    phi = sp.Symbol("phi")
    body = junction_b(["a", "tap", "i", "s"])
    net = Network("scene", {
        "drive": Se(T0), "I1": I(J=J), "node": body, "tap": Tap(),
        "spring_j": junction_a(["a", "b", "c"], "rotational", [1, -1, -1]),
        "C1": C(law=c0 * (1 + eps * sp.cos(z * phi)) * LAW_Q), "wall": Sf(0)},
        [["drive.p", "node.a"], ["node.tap", "tap.p"], ["node.i", "I1.p"], ["node.s", "spring_j.a"],
         ["spring_j.c", "C1.p"], ["spring_j.b", "wall.p"]], signals={"phi": "tap.q"})
    m = _model(net, ["tap.q", "C1.q"])
    res = simulate(m, 3.0, 0.01, rtol=1e-10, atol=1e-12, progress=False)

    def f(t, y):
        p, q, ph = y
        w = p / J
        return [T0 - c0 * (1 + eps * np.cos(z * ph)) * q, w, w]
    ref = solve_ivp(f, (0, 3), [0, 0, 0], t_eval=res.t, rtol=1e-11, atol=1e-13)
    assert np.max(np.abs(res["tap.q"] - ref.y[2])) < 1e-7
    assert np.max(np.abs(res["C1.q"] - ref.y[1])) < 1e-7


def test_multiport_transformer_power_and_kinematics():
    """f_a = K(q)·f_b with a 2x1 matrix: a rotation driving two sliders."""
    q1 = sp.Symbol("q1")
    K = [[sp.cos(q1)], [-sp.sin(q1)]]
    net = Network("scene", {"w": Sf(2.0), "mtf": MTF(K, ["translational"] * 2, ["rotational"]),
                            "s1": Se(1.0, "translational"),
                            "s2": Se(-0.5, "translational")},
                  [["w.p", "mtf.b1"], ["mtf.a1", "s1.p"], ["mtf.a2", "s2.p"]])
    m = _model(net, ["mtf.a1.f", "mtf.a2.f", "mtf.b1.e", "mtf.q1"])
    for t in (0.0, 0.3, 1.1):
        x = np.array([2.0 * t])
        v = m.port_values(t, x)
        q = 2.0 * t
        assert np.isclose(v["mtf.a1.f"], np.cos(q) * 2.0) and np.isclose(v["mtf.a2.f"], -np.sin(q) * 2.0)
        power = sum(v[f"mtf.{p}.e"] * v[f"mtf.{p}.f"] for p in ("a1", "a2", "b1"))
        assert abs(power) < 1e-12


def test_cfield_is_reciprocal_and_conservative():
    S = [[2.0, 0.5], [0.5, 1.0]]          # compliance matrix
    net = Network("scene", {"f1": Sf(sp.sin(T), "translational"), "f2": Sf(0.3, "electrical"), "cf": CField(S, ["translational", "electrical"])},
                  [["f1.p", "cf.p1"], ["f2.p", "cf.p2"]])
    m = _model(net, ["cf.p1.e", "cf.p2.e"])
    x = np.array([0.4, -0.2])
    e = np.linalg.solve(np.array(S), x)
    v = m.port_values(0.0, x)
    assert np.allclose([v["cf.p1.e"], v["cf.p2.e"]], e, rtol=1e-12)


def _imports(path):
    """Module names imported by the Python file ``path`` (absolute and relative imports)."""
    import ast
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            out.append("." * node.level + (node.module or ""))
    return out


def test_layering_kernel_never_imports_elements_and_elements_use_the_public_api():
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    kernel = {p.relative_to(root).as_posix(): _imports(p) for p in (root / "multipole").rglob("*.py")}
    bad = {p: [m for m in mods if m.split(".")[0] == "elements"] for p, mods in kernel.items()}
    assert not {p: m for p, m in bad.items() if m}, "the kernel must not import the element library"
    library = {p.name: _imports(p) for p in (root / "elements").glob("*.py")}
    private = {p: [m for m in mods if m.startswith("multipole.")] for p, mods in library.items()}
    assert not {p: m for p, m in private.items() if m}, "elements must import from the package `multipole` only"
