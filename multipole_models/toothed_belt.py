"""Hand-written numpy model of the toothed belt with two non-circular wheels (Ebert 7.3.2,
``diagrams/belts/toothed_belt.yaml``), the bench's reference for the generated code of that scene.

Written from the physics in ``docs/belts.md`` ("Curve rolls", "Toothed belt with two non-circular
wheels"), not from the generated code.  The wheels' contours enter only through the trigonometric
series of their support functions (``Contour.series``: lever arm ``p(nu)`` and arc length ``S(nu)``),
the same smooth form the elements use; everything else is written out here:

* wheel k turned by ``phi_k`` [rad]; a span of inclination ``gamma`` leaving it at its port j with
  contact side +1 touches the contour point of normal ``nu = gamma + pi/2 - phi_k``; the port's
  winding sense is ``w_j`` = +1 at e1, -1 at e2 (``w = 1``);
* material paid into the span at that end: ``w_j p(nu) omega_k`` [m/s]; wound length
  ``w_j (S(nu0) - S(nu))`` [m]; the torque of the span's tension F on the wheel: ``+w_j p(nu) F``
  (a span pulls material off the wheel: paid out under tension, the wheel is driven);
* a span (EA [N], cd [N s], free length ``l0`` plus the wound lengths at both ends ``lx``): stretch
  ``delta`` [m] with ``delta' = -(material paid in at both ends)``, tension-only Kelvin-Voigt force
  ``F = EA/lx*max(delta, 0) + [delta > 0]*max(-EA/lx*delta, cd/lx*delta')`` (damping never makes
  the span push);
* wheel 1 is driven at the speed ``w`` (its angle is a state), wheel 2 (inertia J2) carries the
  load torque ``-T``: ``p2' = -T + torques of both spans``.

States (the kernel's names): ``wheel1.tap.q`` (phi1), ``wheel2.J.p`` (J2 omega2), ``wheel2.tap.q``
(phi2), ``top.c.q``, ``bottom.c.q`` (stretches).  The Jacobian is written out too (``jac``: taut spans whose
damping does not clip, else a span's force and its derivatives are 0).  Registered as the ``belts`` entry of
``multipole.hand_models`` for scenes with ``reference: {hand_model: toothed_belt}``.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from . import HandModel

HALF_PI = math.pi / 2


# -------------------------------------------------------------------------------------------------
# design of the pitch curves: the code that writes the scene's two contour tables (for
# diagrams/belts/ through diagrams/belts/toothed_belt_design.py, and for the default bench set)

A = 0.8                    #: centre distance [m]
E = 0.2                    #: ratio fluctuation: i_max/i_min = (1 + E)/(1 - E) = 1.5
C = 2.0 / math.sqrt(1 - E * E)
Q = math.sqrt((1 - E) / (1 + E))
R2 = 0.16                  #: mean lever arm of wheel 2 [m]
E2 = 0.04                  #: lobe depth of wheel 2 (wheel 1 takes the rest of the ratio's swing)
N = 1440                   #: table rows
#: the contour tables the scene names (``contour:`` of wheel1 and wheel2), beside the netlist
TABLE_FILES = ("toothed_belt_wheel1.csv", "toothed_belt_wheel2.csv")


def ratio(phi1):
    """Prescribed ratio i = phi1'/phi2' of the drive angle ``phi1`` [rad]."""
    return C * (1 + E * np.cos(2 * phi1))


def phi2_of(phi1):
    """Wheel 2's angle [rad] for wheel 1's (closed-form quadrature of dphi2 = dphi1/i)."""
    phi1 = np.asarray(phi1, dtype=float)
    base = np.arctan2(Q * np.sin(phi1), np.cos(phi1))
    return 0.5 * (base + 2 * math.pi * np.round((phi1 - base) / (2 * math.pi)))


def wheel2_support(nu):
    """p2(nu) [m] and dp2/dnu: R2 (1 + E2 cos 4 nu), four gentle lobes."""
    return R2 * (1 + E2 * np.cos(4 * nu)), -4 * R2 * E2 * np.sin(4 * nu)


def wheel1_support(nu):
    """p1(nu) [m] and dp1/dnu from the rolling condition p1(pi/2 - phi1) = p2(pi/2 - phi2(phi1))/i(phi1)."""
    phi1 = math.pi / 2 - np.asarray(nu, dtype=float)
    i = ratio(phi1)
    p2, dp2 = wheel2_support(math.pi / 2 - phi2_of(phi1))
    di = -2 * C * E * np.sin(2 * phi1)
    dp1_dphi1 = (-dp2 / i * i - p2 * di) / i ** 2          # dnu2/dphi1 = -1/i
    return p2 / i, -dp1_dphi1


def contour_tables() -> dict:
    """``{file name: (theta [rad], r [m])}`` of the two pitch curves in polar form (roll frame), by
    increasing theta, as the scene's tables hold them."""
    from elements.belt_contour import polar_from_support
    nu = np.linspace(0.0, 2 * math.pi, N, endpoint=False)
    out = {}
    for name, (p, dp) in zip(TABLE_FILES, (wheel1_support(nu), wheel2_support(nu))):
        th, r = polar_from_support(p, dp, nu)
        order = np.argsort(th)
        th, r = th[order], r[order]
        keep = np.concatenate([[True], np.diff(th) > 1e-12])
        out[name] = th[keep], r[keep]
    return out


def table_texts() -> dict:
    """``{file name: text}`` of the two contour tables in the format ``elements.belt_contour`` reads."""
    from elements.belt_contour import table_text
    return {name: table_text(th, r, f"toothed belt (Ebert 7.3.2) {name[len('toothed_belt_'):-len('.csv')]} "
                             "pitch curve, made by diagrams/belts/toothed_belt_design.py")
            for name, (th, r) in contour_tables().items()}


class _Series:
    """p(nu) and S(nu) [m] of a contour from its support function's Fourier coefficients ``a``, ``b``
    (p = a0 + sum a_k cos k nu + b_k sin k nu; S = a0 nu + sum a_k (1/k - k) sin k nu
    + b_k (k - 1/k)(cos k nu - 1): dS/dnu = p + p'')."""

    def __init__(self, a, b):
        self.a, self.b = np.asarray(a, float), np.asarray(b, float)
        self.k = np.arange(1, len(self.a), dtype=float)

    def p(self, nu):
        kn = np.multiply.outer(np.asarray(nu, float), self.k)
        return self.a[0] + np.cos(kn) @ self.a[1:] + np.sin(kn) @ self.b[1:]

    def dp(self, nu):
        kn = np.multiply.outer(np.asarray(nu, float), self.k)
        return np.cos(kn) @ (self.k * self.b[1:]) - np.sin(kn) @ (self.k * self.a[1:])

    def d2p(self, nu):
        kn = np.multiply.outer(np.asarray(nu, float), self.k)
        return -(np.cos(kn) @ (self.k ** 2 * self.a[1:]) + np.sin(kn) @ (self.k ** 2 * self.b[1:]))

    def S(self, nu):
        nu = np.asarray(nu, float)
        kn = np.multiply.outer(nu, self.k)
        return (self.a[0] * nu + np.sin(kn) @ (self.a[1:] * (1 / self.k - self.k))
                + (np.cos(kn) - 1) @ (self.b[1:] * (self.k - 1 / self.k)))


def toothed_belt_hand(params: dict, folder: Path, tol: float = 1e-9) -> HandModel:
    """The hand-written model of ``toothed_belt.yaml`` (parameters ``params`` of the scene, contour
    tables in ``folder``; ``tol`` [m]: the series' tolerance, the elements' default)."""
    from elements.belt_contour import read_table

    def series(name):
        return _Series(*read_table(str(folder / name)).series(tol))

    c1, c2 = series("toothed_belt_wheel1.csv"), series("toothed_belt_wheel2.csv")
    w, EA, cd, l, F0, T = (params[k] for k in ("w", "EA", "cd", "l", "F0", "T"))
    dF = T / (2 * 0.1664)
    J2 = 0.05
    omega20 = w / (2 / math.sqrt(1 - 0.2 ** 2) * 1.2)
    l0_top, l0_bot = l / (1 + (F0 + dF) / EA), l / (1 + (F0 - dF) / EA)
    g_top, g_bot = 0.0, math.pi
    # (wheel series, span gamma, winding sense of the port): wheel1.e1-bottom.e2, wheel1.e2-top.e1,
    # wheel2.e1-top.e2, wheel2.e2-bottom.e1
    n1b, n1t = g_bot + HALF_PI, g_top + HALF_PI          # nu at phi = 0

    def ends(phi1, phi2):
        """Lever arms [m] and wound lengths [m] of the four span ends."""
        p1b, p1t = c1.p(n1b - phi1), c1.p(n1t - phi1)
        p2t, p2b = c2.p(n1t - phi2), c2.p(n1b - phi2)
        l1b = +(c1.S(n1b) - c1.S(n1b - phi1))
        l1t = -(c1.S(n1t) - c1.S(n1t - phi1))
        l2t = +(c2.S(n1t) - c2.S(n1t - phi2))
        l2b = -(c2.S(n1b) - c2.S(n1b - phi2))
        return p1b, p1t, p2t, p2b, l1b, l1t, l2t, l2b

    def force(delta, rate, lx):
        k, b = EA / lx, cd / lx
        return k * np.maximum(delta, 0) + (delta > 0) * np.maximum(-k * delta, b * rate)

    def parts(x):
        phi1, p2, phi2, dt, db = x
        om2 = p2 / J2
        p1b, p1t, p2t, p2b, l1b, l1t, l2t, l2b = ends(phi1, phi2)
        rate_t = -(-p1t * w + p2t * om2)                 # top: wheel1.e2 (w = -1), wheel2.e1 (w = +1)
        rate_b = -(p1b * w - p2b * om2)                  # bottom: wheel1.e1 (+1), wheel2.e2 (-1)
        Ft = force(dt, rate_t, l0_top + l1t + l2t)
        Fb = force(db, rate_b, l0_bot + l1b + l2b)
        return om2, rate_t, rate_b, Ft, Fb, p2t, p2b, p1t, p1b

    def rhs(t, x):
        om2, rate_t, rate_b, Ft, Fb, p2t, p2b, _, _ = parts(x)
        return np.array([w, -T + p2t * Ft - p2b * Fb, om2, rate_t, rate_b])

    def jac(t, x):
        """Analytic Jacobian of :func:`rhs` (d(nu)/d(phi) = -1, dS/dnu = p + p'')."""
        phi1, p2, phi2, dt, db = x
        om2, rate_t, rate_b, Ft, Fb, p2t, p2b, p1t, p1b = parts(x)
        a1t, a1b, a2t, a2b = n1t - phi1, n1b - phi1, n1t - phi2, n1b - phi2
        # gradients over (phi1, p2, phi2, dt, db)
        g_rt = np.array([-c1.dp(a1t) * w, -p2t / J2, c2.dp(a2t) * om2, 0.0, 0.0])
        g_rb = np.array([c1.dp(a1b) * w, p2b / J2, -c2.dp(a2b) * om2, 0.0, 0.0])
        g_lt = np.array([-(c1.p(a1t) + c1.d2p(a1t)), 0.0, c2.p(a2t) + c2.d2p(a2t), 0.0, 0.0])
        g_lb = np.array([c1.p(a1b) + c1.d2p(a1b), 0.0, -(c2.p(a2b) + c2.d2p(a2b)), 0.0, 0.0])
        l1b, l1t, l2t, l2b = ends(phi1, phi2)[4:]

        def g_force(delta, rate, lx, k_delta, g_rate, g_lx, F):
            if not (delta > 0 and cd / lx * rate > -EA / lx * delta):   # slack, or damping would push: F = 0
                return np.zeros(5)
            g_delta = np.zeros(5)
            g_delta[k_delta] = 1.0
            return (EA * g_delta + cd * g_rate) / lx - F / lx * g_lx

        g_Ft = g_force(dt, rate_t, l0_top + l1t + l2t, 3, g_rt, g_lt, Ft)
        g_Fb = g_force(db, rate_b, l0_bot + l1b + l2b, 4, g_rb, g_lb, Fb)
        row1 = p2t * g_Ft - p2b * g_Fb
        row1[2] += -c2.dp(a2t) * Ft + c2.dp(a2b) * Fb
        return np.array([np.zeros(5), row1, [0.0, 1 / J2, 0.0, 0.0, 0.0], g_rt, g_rb])

    def out_F(which):
        def g(t, X):
            return np.array([parts(X[:, i])[3 + which] for i in range(X.shape[1])])
        return g

    x0 = np.array([0.0, J2 * omega20, 0.0, l - l0_top, l - l0_bot])
    return HandModel("toothed_belt", ["wheel1.tap.q", "wheel2.J.p", "wheel2.tap.q", "top.c.q", "bottom.c.q"],
                     x0, rhs, jac,
                     {"wheel1.phi": lambda t, X: X[0], "wheel2.phi": lambda t, X: X[2],
                      "wheel1.omega": lambda t, X: np.full(X.shape[1], w), "wheel2.omega": lambda t, X: X[1] / J2,
                      "top.F": out_F(0), "bottom.F": out_F(1)})


def hand_model(scene) -> HandModel | None:
    """The toothed-belt hand model for a scene naming ``reference: {hand_model: toothed_belt}`` (its
    contour tables beside the scene file), else ``None``."""
    if (scene.reference or {}).get("hand_model") != "toothed_belt" or not scene.path:
        return None
    params = {k: float(v) for k, v in scene.network.params.items() if _is_number(v)}
    return toothed_belt_hand(params, Path(scene.path).parent)


def _is_number(v) -> bool:
    try:
        float(v)
        return True
    except (TypeError, ValueError):
        return False
