"""Hand-written numpy models of the bench scenes against the generated models.

The hand-written models (``multipole_models``) are written from the physics; the generated ones
come out of the causality analyser and the code generator.  Agreement of right-hand sides,
Jacobians and outputs at random states, to round-off, checks both: neither side is derived from the
other.  The bench finds hand models through the ``multipole.hand_models`` entry points only.
Every default bench scene has one, unless its ``reference`` mapping says why not (``no_hand_model``).
"""
import ast
import math
from pathlib import Path

import numpy as np
import pytest

import multipole_models as S
from multipole import pipeline
from multipole.bench import default_scenes, hand_model, reference_spec, solve_hand
from multipole.netlist import load, loads

ROOT = Path(__file__).resolve().parents[1]
BENCH = default_scenes()
#: the default scenes that have a hand-written model (every one that does not declare why it has none)
HANDED = [sc for sc in BENCH if "no_hand_model" not in reference_spec(sc)]
ROUND_OFF = 1e-12


@pytest.fixture(scope="module", params=HANDED, ids=lambda sc: sc.name)
def pair(request):
    scene = request.param
    return scene, pipeline.model(scene), hand_model(scene)


def _states(model, t_end, n=24, seed=0):
    """Random (t, x): x0 plus perturbations of every size from 1e-7 to 10 (relative to max(|x0|, 1)),
    so that switching laws are sampled on both sides (rope taut and slack, friction sticking and
    slipping) and nonlinear loops over a wide range of slip speeds."""
    rng = np.random.default_rng(seed)
    base = np.maximum(np.abs(model.x0), 1.0)
    for k in range(n):
        scale = 10.0 ** rng.uniform(-7, 1)
        yield float(rng.uniform(0, t_end)), model.x0 + scale * base * rng.normal(size=len(model.x0))


def _t_end(scene):
    return float(scene.simulate.get("t_end", 1.0))


def test_every_bench_scene_has_a_hand_model_with_the_same_states_or_says_why_not():
    assert len(BENCH) == 11
    without = {sc.name: reference_spec(sc)["no_hand_model"] for sc in BENCH if sc not in HANDED}
    assert list(without) == ["compressor"]                 # the one declared exception, with its reason
    assert "planar span geometry" in without["compressor"]
    assert hand_model(next(sc for sc in BENCH if sc.name == "compressor")) is None
    for scene in HANDED:
        model, hand = pipeline.model(scene), hand_model(scene)
        assert hand is not None, scene.name
        assert sorted(hand.state_names) == sorted(model.state_names), scene.name
        idx = hand.permutation(model.state_names)
        assert np.array_equal(hand.x0, model.x0[idx]), scene.name


def test_rhs_equals_generated_at_random_states(pair):
    scene, model, hand = pair
    idx = hand.permutation(model.state_names)
    for t, x in _states(model, _t_end(scene)):
        gen, own = model.rhs(t, x)[idx], hand.rhs(t, x[idx])
        assert np.max(np.abs(gen - own)) <= ROUND_OFF * max(1.0, np.max(np.abs(own))), (scene.name, t, x)


def test_jacobian_equals_generated_at_random_states(pair):
    scene, model, hand = pair
    assert hand.jac is not None
    idx = hand.permutation(model.state_names)
    for t, x in _states(model, _t_end(scene), seed=1):
        gen, own = model.jac(t, x)[np.ix_(idx, idx)], np.asarray(hand.jac(t, x[idx]))
        assert np.max(np.abs(gen - own)) <= ROUND_OFF * max(1.0, np.max(np.abs(own))), (scene.name, t, x)


def test_hand_outputs_equal_generated_outputs(pair):
    scene, model, hand = pair
    idx = hand.permutation(model.state_names)
    points = list(_states(model, _t_end(scene), n=6, seed=2))
    t = np.array([p[0] for p in points])
    X = np.array([p[1] for p in points]).T                       # (n_states, n_times), generated order
    common = [o for o in model.output_names if o in hand.outputs]
    assert common, scene.name
    for name in common:
        k = model.output_names.index(name)
        gen = np.array([model.outputs(ti, X[:, j])[k] for j, ti in enumerate(t)])
        own = np.asarray(hand.outputs[name](t, X[idx]), dtype=float)
        assert np.allclose(own, gen, rtol=ROUND_OFF, atol=ROUND_OFF), (scene.name, name)


def test_reference_output_of_every_bench_scene_is_a_hand_output():
    for scene in HANDED:
        assert reference_spec(scene)["output"] in hand_model(scene).outputs, scene.name


# -------------------------------------------------------------------------------------------------
# the laws themselves, against theory

def test_slack_rope_hand_model_pulls_only_when_taut():
    hand = S._slack_rope_hand({})
    m, k, g = 10.0, 1.0e4, 9.81
    assert hand.rhs(0.0, np.array([0.05, 2.0])) == pytest.approx([0.2, -m * g])            # slack: free fall
    assert hand.rhs(0.0, np.array([-0.01, 0.0])) == pytest.approx([0.0, -m * g + k * 0.01])  # taut


def test_stick_slip_friction_reaches_the_static_level_near_zero_slip():
    hand = S._stick_slip_hand({})
    m, v_belt, k = 1.0, 0.1, 100.0
    # slip speed f = v_belt - v: at f = 10 v_reg the tanh is 1 - 4e-9 and the Stribeck term exp(-1e-4)
    f = 1e-5
    F = hand.rhs(0.0, np.array([m * (v_belt - f), 0.0]))[0]
    assert F == pytest.approx(6.0 + 4.0 * math.exp(-(f / 1e-4) ** 2), rel=1e-8)
    # far from sticking: the kinetic level, minus the spring
    assert hand.rhs(0.0, np.array([m * (v_belt - 0.05), 0.01]))[0] == pytest.approx(6.0 - k * 0.01, rel=1e-12)


def test_nonlinear_loop_force_balances_both_dampers():
    hand = S._loop_hand({})
    m, V, w, d1, k1, a2, b2 = 2.0, 3.0, 2.0, 1.5, 4.0, 1.0, 0.5
    for t, p in ((0.3, -1.0), (1.1, 4.0), (2.0, 0.0)):
        F = hand.rhs(t, np.array([p]))[0]
        delta = V * math.sin(w * t) - p / m
        s = b2 * math.asinh(F / a2)                  # slip of the second damper from its force
        f1 = delta - s                               # the first damper carries the same force
        assert d1 * f1 + k1 * f1**3 == pytest.approx(F, rel=1e-12, abs=1e-12)


def test_slider_crank_kinematics_against_finite_differences():
    r, l = 0.05, 0.2
    for phi in (0.0, 0.4, 1.3, 2.9, 4.0):
        d1, d2, d3 = S._crank_kinematics(phi, r, l)
        h = 1e-4
        x = [S.slider_crank_position(phi + j * h, r, l) for j in (-1, 0, 1)]
        assert d1 == pytest.approx((x[2] - x[0]) / (2 * h), rel=1e-6, abs=1e-9)
        assert d2 == pytest.approx((x[2] - 2 * x[1] + x[0]) / h**2, rel=1e-5, abs=1e-7)
        h = 1e-3                     # third difference: round-off ~ 1e-16 x/h³, truncation ~ h² x⁽⁵⁾
        x = [S.slider_crank_position(phi + j * h, r, l) for j in (-2, -1, 1, 2)]
        assert d3 == pytest.approx((x[3] - 2 * x[2] + 2 * x[1] - x[0]) / (2 * h**3), rel=1e-4, abs=1e-6)


def test_hand_run_of_a_linear_scene_matches_its_closed_form():
    """solve_hand (what the bench times) against the modal closed form of the RLC step response."""
    scene = loads(S.rlc_series(), "rlc_series.yaml")
    hand = hand_model(scene)
    t = np.linspace(0.0, 0.1, 201)
    res = solve_hand(hand, 0.1, t, "DOP853", 1e-10, 1e-13)
    R, L, C, V = 10.0, 0.1, 1.0e-4, 12.0
    alpha, w0 = R / (2 * L), 1 / math.sqrt(L * C)                 # underdamped: alpha = 50 < w0 = 316 1/s
    wd = math.sqrt(w0**2 - alpha**2)
    exact = V * (1 - np.exp(-alpha * t) * (np.cos(wd * t) + alpha / wd * np.sin(wd * t)))
    assert np.max(np.abs(res["C1.v"] - exact)) < 1e-6 * V
    assert res.stats["nfev"] > 0


def test_hand_run_stops_at_its_evaluation_budget():
    hand = hand_model(loads(S.mathieu_oscillator(), "mathieu.yaml"))
    with pytest.raises(RuntimeError, match="right-hand side calls"):
        solve_hand(hand, 100.0, np.linspace(0, 100.0, 11), "RK45", 1e-10, 1e-12, max_nfev=500)


# -------------------------------------------------------------------------------------------------
# the kernel finds hand models through entry points only

def test_hand_models_come_through_the_entry_point_group():
    from importlib.metadata import entry_points
    eps = entry_points(group="multipole.hand_models")
    assert any(ep.value == "multipole_models:hand_model" for ep in eps)
    assert hand_model(loads(S.mathieu_oscillator(), "m.yaml")) is not None
    other = load(ROOT / "diagrams" / "power_split_rigid.yaml")
    assert hand_model(other) is None


def test_the_kernel_imports_no_element_library():
    for path in sorted((ROOT / "multipole").rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
            assert not any(n == "elements" or n.startswith("elements.") for n in names), path
    bench = (ROOT / "multipole" / "bench.py").read_text(encoding="utf-8")
    assert "elements" not in bench and "multipole_models" not in bench   # found through entry points only
