"""DB~DS and DB~DD band-curve synthesis (Ebert 4.3.1, 7.2.2): a band tied to a linkage point.

Closed forms: a band wound on a circle of radius R about the cam pivot, pulled by a slider on a
guide through the pivot (DB~DS) or by a rocker (DB~DD).  Its length |S - C| + R (cam angle - angle
of the tangent point C) is constant, which gives the cam angle as a function of the joint's position;
the synthesis of that motion must give back the circle (radius R, lever arm R, free length the
tangent length sqrt(|S|^2 - R^2)).  The scene diagrams/belts/db_ds_slider.py is checked by its
round trip through the contour table with the curve roll's geometry.
"""
import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import optimize

from elements.belt_contour import read_table
from elements.belt_synthesis import DBDD, DBDS, Transfer, attached_trace, band_curve, synthesise_contour
from multipole import ModelError

ROOT = Path(__file__).resolve().parents[1]
R = 0.04          # m: the circular cam


def _scene_module():
    spec = importlib.util.spec_from_file_location("db_ds_slider", ROOT / "diagrams" / "belts" / "db_ds_slider.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod                      # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _g(a):
    """s - R * alpha for the joint a (shape (n, 2)): free tangent length minus R times the polar
    angle of the upper tangent point; the band length is const + R*c - g."""
    d = np.hypot(*a.T)
    return np.sqrt(d * d - R * R) - R * (np.arctan2(a[:, 1], a[:, 0]) + np.arccos(R / d))


def _slider_on_circle(x0=0.2):
    """x(c) for the slider at (x, 0) on the circle: c = (g(x0) - g(x))/R, inverted; x' = -R x/s,
    x'' = R^3 x'/s^3 (s = sqrt(x^2 - R^2))."""
    def g1(x):
        return math.sqrt(x * x - R * R) - R * math.acos(R / x)

    def x(c):
        c = np.atleast_1d(np.asarray(c, float))
        return np.array([optimize.brentq(lambda v: (g1(x0) - g1(v)) / R - ci, R * (1 + 1e-9), x0 * 10,
                                         xtol=1e-16, rtol=1e-15) for ci in c])

    def dx(c):
        v = x(c)
        return -R * v / np.sqrt(v * v - R * R)

    def ddx(c):
        v = x(c)
        s = np.sqrt(v * v - R * R)
        return R ** 3 * (-R * v / s) / s ** 3

    return Transfer(x, dx, ddx)


def test_db_ds_slider_on_a_circle_gives_the_circle():
    x = _slider_on_circle()
    phi = np.linspace(0.0, 1.5, 301)                 # the slider runs from 0.2 m toward the cam
    tr = DBDS((0.0, 0.0)).trace(phi, x)
    curve = band_curve(tr)
    xs = x(phi)
    assert xs[-1] < 0.15                              # the motion is a real stretch of travel
    np.testing.assert_allclose(np.hypot(*curve.contour.T), R, rtol=0, atol=1e-9)
    np.testing.assert_allclose(curve.free_length, np.sqrt(xs * xs - R * R), rtol=0, atol=1e-9)
    # the band is wound on (K = +1, counter-clockwise): lever +R, the foot 23 on the circle
    np.testing.assert_allclose(tr.lever, R, rtol=1e-9)
    np.testing.assert_allclose(np.hypot(*tr.foot.T), R, rtol=1e-9)


def test_db_ds_guide_off_the_pivot_and_mirrored():
    """The same circle seen from a guide through (0, 0.05) at 30 deg: shifting and turning the
    frame must not change the contour; K = -1 (cam turning clockwise, the joint mirrored about the
    guide) gives the mirrored circle, the same radius."""
    x = _slider_on_circle()
    phi = np.linspace(0.0, 1.5, 301)
    a = math.radians(30.0)
    p1 = np.array([0.0, 0.05]) + 0.3 * np.array([math.cos(a), math.sin(a)])   # the pivot on the guide
    for K in (1, -1):
        tr = DBDS(p1, (0.0, 0.05), a, K=K).trace(phi, Transfer(lambda p: 0.3 + x(p), lambda p: x(p, 1), lambda p: x(p, 2)))
        curve = band_curve(tr)
        np.testing.assert_allclose(np.hypot(*curve.contour.T), R, rtol=0, atol=1e-9)


def test_db_dd_rocker_on_a_circle_gives_the_circle():
    """A rocker (pivot (0.15, 0.1), length 0.1 m) pulled by the band on the circle: the cam angle
    c(psi) = (g(A(psi0)) - g(A(psi)))/R in closed form, its inverse psi(c) a quintic spline through
    2001 samples (interpolation error far below the tolerance)."""
    p2, L = np.array([0.15, 0.1]), 0.1
    psi = np.linspace(-0.2, -2.3, 2001)               # the rocker swings clockwise as the cam winds on
    A = p2 + L * np.stack([np.cos(psi), np.sin(psi)], -1)
    c = (_g(A[:1]) - _g(A)) / R
    assert np.all(np.diff(c) > 0)
    tf = Transfer.from_table(c, psi)
    phi = np.linspace(c[0] + 0.05, c[-1] - 0.05, 401)
    curve = band_curve(DBDD((0.0, 0.0), p2, L).trace(phi, tf))
    np.testing.assert_allclose(np.hypot(*curve.contour.T), R, rtol=0, atol=1e-7)


def test_linkage_band_errors():
    with pytest.raises(ModelError) as exc:
        attached_trace([0.0, 1.0], (0, 0), np.ones((2, 2)), np.ones((2, 2)), np.ones((2, 2)), K=2)
    assert exc.value.code == "bad_assembly_mode"
    with pytest.raises(ModelError) as exc:
        DBDD((0, 0), (0.1, 0), 0.0).trace([0.0, 1.0], Transfer(np.sin, np.cos, lambda p: -np.sin(p)))
    assert exc.value.code == "bad_length"


def test_db_ds_slider_scene_round_trip(tmp_path):
    """Ebert 7.2.2: producible (no sign change of dl_Bf/dphi), free length and cam size as he
    reports them (100 .. 350 mm, about 120 mm; our motion law: the figure is missing), and the
    slider placed through the closed cam table by the curve roll's geometry follows the prescribed
    x(phi).  Tolerance: the table's spline error eps (measured against the exact evolute between
    the table's points) moves the tangent by eps and the wrapped arc by at most its length times
    the spline's slope error eps/dtheta; the slider moves by that times x/|h| (the guide meets the
    band at the angle whose cosine is |h|/x)."""
    mod = _scene_module()
    scene = mod.SliderScene()
    arc, cam = tmp_path / "arc.csv", tmp_path / "cam.csv"
    syn = mod.synthesise(scene, arc=arc, cam=cam)
    a = syn.assessment
    assert a.producible
    assert 0.09 < a.free_length.min() < 0.11 and 0.33 < a.free_length.max() < 0.36
    assert 0.11 < a.max_radius < 0.125
    phi = syn.curve.phi
    mid = 0.5 * (phi[1:] + phi[:-1])
    exact = band_curve(scene.structure().trace(mid, scene.transfer())).contour
    table = read_table(cam)
    th = np.arctan2(exact[:, 1], exact[:, 0])
    eps = float(np.max(np.abs(table.radius(th) - np.hypot(*exact.T))))
    dtheta = float(np.max(np.abs(np.diff(syn.theta))))
    arc_length = float(np.sum(np.hypot(*np.diff(syn.curve.contour, axis=0).T)))
    ratio = float(np.max(scene.transfer()(phi) / np.abs(syn.trace.lever)))
    tol = ratio * (eps + arc_length * eps / dtheta)
    assert tol < 1e-6                                   # the bound itself is meaningful
    check = np.linspace(0.0, scene.phi_end, 30)
    x, theta = mod.slider_through_table(cam, check, scene.x0, scene.K, scene.side)
    np.testing.assert_allclose(x, scene.transfer()(check), rtol=0, atol=tol)
    # the band touches only the synthesised arc, never the closing part (the first contact is the
    # arc's end point, found through the spline: 1e-6 rad of slack at both ends)
    t0, t1 = syn.theta[0], syn.theta[-1]
    base = t0 + np.mod(theta - t0 + 1e-6, 2 * math.pi) - 1e-6
    assert np.all(base <= t1 + 1e-6)


def test_db_ds_slider_tables_are_current(tmp_path):
    """The committed tables are what the script writes now (same points to 1e-12 m)."""
    mod = _scene_module()
    mod.synthesise(mod.SliderScene(), arc=tmp_path / "arc.csv", cam=tmp_path / "cam.csv")
    mod.guided_cam(mod.SliderScene(), tmp_path / "guided.csv")
    for new, old in ((tmp_path / "arc.csv", mod.ARC), (tmp_path / "cam.csv", mod.CAM),
                     (tmp_path / "guided.csv", mod.GUIDED_CAM)):
        a, b = np.loadtxt(new, delimiter=",", skiprows=1), np.loadtxt(old, delimiter=",", skiprows=1)
        assert a.shape == b.shape
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


def test_db_ds_guided_scene_follows_the_law():
    """diagrams/belts/db_ds_slider_guided.yaml (the 1-D limit: guide parallel to the band): the cam
    turned at w = 0.5 rad/s through 2.9 rad pulls the slider by the prescribed travel x(phi) - x0
    less the band's change of stretch.  Tolerance: the curve drum's series error of the wound length
    (Contour.series_error at the scene's tol) plus the integrator's rtol 1e-9 on the 0.3 m travel;
    the lever arm h1 is the law's x'(phi) to the scene's tol = 1e-7 m (the curve drum's bound on its
    series' lever error) plus 1e-9 m for the table spline (its radial error is 5e-11 m, see the
    round trip test)."""
    mod = _scene_module()
    scene = mod.SliderScene()
    phi, travel, stretch, out = mod.run_guided()
    assert phi[-1] == pytest.approx(scene.phi_end, abs=1e-9)
    assert np.all(out["cam.F1"] > 0)                   # the band stays taut
    cam = read_table(mod.GUIDED_CAM)
    cam.series(1e-7)                                    # the scene's tol
    wound_err = cam.series_error[1]
    x = scene.transfer()
    np.testing.assert_allclose(travel + (stretch - stretch[0]), x(phi) - scene.x0, rtol=0,
                               atol=wound_err + 1e-9 * 0.3)
    np.testing.assert_allclose(out["cam.h1"], x(phi, 1), rtol=0, atol=1e-7 + 1e-9)
