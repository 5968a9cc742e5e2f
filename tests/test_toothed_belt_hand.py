"""The hand-written toothed-belt model (multipole_models/toothed_belt.py) against the generated one.

The hand model is written from the physics of docs/belts.md (lever arms and wound lengths from the
contours' series, tension-only spans); the generated model comes out of the causality analysis and
the code generator.  Neither is derived from the other, so agreement to round-off at random states
(spans taut and slack, stretching and relaxing) checks both.  The bench finds the hand model only
through the ``multipole.hand_models`` entry points.
"""
from pathlib import Path

import numpy as np
import pytest

from multipole import pipeline
from multipole.bench import hand_model
from multipole.netlist import load

SCENE = Path(__file__).resolve().parents[1] / "diagrams" / "belts" / "toothed_belt.yaml"


@pytest.fixture(scope="module")
def pair():
    scene = load(SCENE)
    return scene, pipeline.model(scene), hand_model(scene)


def test_found_through_the_entry_points_with_the_generated_states(pair):
    scene, model, hand = pair
    assert hand is not None and hand.name == "toothed_belt"
    assert sorted(hand.state_names) == sorted(model.state_names)
    idx = hand.permutation(model.state_names)
    np.testing.assert_allclose(hand.x0, model.x0[idx], rtol=1e-14, atol=0)


def test_rhs_equals_generated_at_random_states(pair):
    """Angles over several turns, wheel-2 speeds around its mean, stretches of both signs (a slack
    span: force 0) and of every size: the right-hand sides agree to round-off (the series' terms
    below 1e-9 m the elements drop move the lever arms by less than 1e-8 relative)."""
    scene, model, hand = pair
    idx = hand.permutation(model.state_names)
    rng = np.random.default_rng(1)
    scale = np.array([10.0, 0.1, 10.0, 2e-3, 2e-3])           # phi1, p2, phi2, stretches
    slack = 0
    for _ in range(300):
        x = model.x0 + scale * 10.0 ** rng.uniform(-4, 0, 5) * rng.normal(size=5)
        slack += x[list(model.state_names).index("top.c.q")] < 0
        t = float(rng.uniform(0.0, 2.0))
        gen, own = model.rhs(t, x)[idx], hand.rhs(t, x[idx])
        np.testing.assert_allclose(own, gen, rtol=1e-8, atol=1e-10 * np.max(np.abs(gen)))
    assert slack >= 5                      # the slack side of the law was sampled


def test_outputs_of_a_run_agree(pair):
    """Wheel 2's speed and the top span's force over 0.3 s: the hand model under solve_ivp against
    the generated model's run, both at rtol 1e-10 (difference within a few 1e-8 of the scale)."""
    from scipy.integrate import solve_ivp
    from multipole.simulate import simulate
    scene, model, hand = pair
    res = simulate(model, 0.3, 0.01, "DOP853", 1e-10, 1e-13, progress=False)
    sol = solve_ivp(hand.rhs, (0.0, 0.3), hand.x0, method="DOP853", t_eval=res.t, rtol=1e-10, atol=1e-13)
    for name in ("wheel2.omega", "top.F"):
        own, gen = hand.outputs[name](sol.t, sol.y), np.asarray(res[name])
        assert np.max(np.abs(own - gen)) <= 1e-7 * np.max(np.abs(gen)), name


def test_jacobian_equals_generated_and_differences(pair):
    """The hand-written analytic Jacobian against the generated one (to round-off) and against
    central differences of the hand right-hand side (step 1e-6 of each state's scale: truncation
    O(h^2) and round-off O(eps/h) both below 1e-6 of the entries' scale), the latter at the states
    where each span's law stays on one branch (taut or slack) across the differences."""
    scene, model, hand = pair
    idx = hand.permutation(model.state_names)
    rng = np.random.default_rng(2)
    scale = np.array([10.0, 0.1, 10.0, 2e-3, 2e-3])
    checked = 0
    for _ in range(60):
        x = model.x0 + scale * 10.0 ** rng.uniform(-4, 0, 5) * rng.normal(size=5)
        t = float(rng.uniform(0.0, 2.0))
        gen, own = model.jac(t, x)[np.ix_(idx, idx)], np.asarray(hand.jac(t, x[idx]))
        np.testing.assert_allclose(own, gen, rtol=1e-8, atol=1e-10 * np.max(np.abs(gen)))
        xh = x[idx]
        h = 1e-6 * np.maximum(np.abs(xh), np.array([1.0, 0.1, 1.0, 1e-3, 1e-3]))
        fd, same_branch = np.empty((5, 5)), True
        for j in range(5):
            e = np.zeros(5)
            e[j] = h[j]
            X = np.stack([xh + e, xh - e], axis=1)
            for out in ("top.F", "bottom.F"):      # a span's law on one branch on both sides
                same_branch &= bool(np.all(hand.outputs[out](t, X) > 0) or np.all(hand.outputs[out](t, X) == 0))
            fd[:, j] = (hand.rhs(t, xh + e) - hand.rhs(t, xh - e)) / (2 * h[j])
        if same_branch:
            checked += 1
            np.testing.assert_allclose(fd, own, rtol=1e-5, atol=1e-6 * np.max(np.abs(own)))
    assert checked >= 30
