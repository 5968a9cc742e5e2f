"""Rolls with a convex curve contour after Ebert (2015, 4.4.5): the contour, the curve roll, the curve drum.

The contour is a closed convex curve around the roll's axis, given in polar form ``r(theta)`` in the
roll frame (theta [rad], r [m]), from a table (CSV, :func:`read_table`) or a Python callable, and
turned into a periodic C2 cubic spline (:class:`Contour`).  Convexity is checked when it is made:
the curvature ``kappa = (r^2 + 2 r'^2 - r r'') / (r^2 + r'^2)^(3/2)`` must be > 0 everywhere, else
``contour_not_convex`` names the angle and the curvature where it fails.

Geometry a band sees (all in the roll frame, angles unwrapped):

* ``nu(theta) = theta - atan2(r', r)``: the angle of the outward normal at the contour point of
  polar angle theta; strictly increasing for a convex contour, so every normal direction ``nu``
  has exactly one contact point ``theta(nu)`` (:meth:`Contour.contact`);
* the support function ``p(nu) = r(theta) cos(theta - nu)``: the distance from the axis to the
  tangent line of normal ``nu``, i.e. the lever arm of a band leaving along that tangent
  (:meth:`Contour.support`);
* the arc length ``S(nu)`` from the contact point of ``nu = 0`` (``dS/dnu = p + p''``, the radius of
  curvature; ``S(nu + 2 pi) = S(nu) + perimeter``) (:meth:`Contour.arc`).

A band whose span has the inclination gamma leaves a roll turned by phi at the contact point whose
normal has the global angle ``gamma + side*pi/2`` (``side`` = +1: the roll lies to the right of the
span seen from P1 to P2), i.e. ``nu = gamma + side*pi/2 - phi`` in the roll frame.  The band
material that crossed the contact point since t = 0 is ``w*(S(nu0) - S(nu))`` (the wound length,
Ebert 4.116/4.118 with erratum E4's single winding sense ``w``), and the rate at which the span's
free length grows is ``w*p(nu)*omega``: the material rate plus the contact point's motion along the
span.  The roll is therefore a transformer of ratio ``w*p(nu)`` (lossless: the torque is
``w*p*F``) whose position is the wound length; for a circle both reduce to ``band_roll``.

Generated code cannot call the spline, so the elements use the trigonometric series of ``p``
(:meth:`Contour.series`): ``p = a0 + sum a_k cos(k nu) + b_k sin(k nu)`` with as many harmonics as
make ``p`` and ``S`` (whose series follows from ``p``'s: ``S = a0 nu + sum a_k (1/k - k) sin(k nu)
+ b_k (k - 1/k)(cos(k nu) - 1)``) agree with the spline's to ``tol`` [m]; smooth in nu, so a
revolution costs no events.  Units: SI (m, rad).  Reference: ``docs/belts.md``.
"""
from __future__ import annotations

import csv
import math
import os
import warnings
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np
import sympy as sp

from multipole import Diagnostic, ModelError, Param, Quantity, element, register_check

from .belt import _BAND, _ROLL_QTY, _roll

TWO_PI = 2.0 * math.pi
#: largest contour table accepted [bytes] and its most rows
MAX_TABLE_BYTES, MAX_ROWS = 1 << 20, 20000
#: harmonics the elements' series may use at most
MAX_HARMONICS = 400


def _err(code: str, message: str, fix: str) -> ModelError:
    return ModelError(code, message, fix)


def _where(source: str, lines, k: int) -> str:
    """Point ``k`` named for a message: its table line, else its number."""
    at = lines[k] if lines and k < len(lines) else None
    return source + (f" line {at}" if isinstance(at, int) else f" {at}" if at else f" point {k + 1}")


def _check_points(theta, r, source: str, lines=None, least: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """The points of a contour or an arc as float arrays, checked: at least ``least`` of them, finite,
    theta [rad] strictly increasing, r [m] > 0; errors name the table line (``lines[k]``)."""
    th, r = np.asarray(theta, dtype=float), np.asarray(r, dtype=float)
    where = partial(_where, source, lines)
    if th.ndim != 1 or th.shape != r.shape or len(th) < least:
        raise _err("bad_contour", f"{source}: a contour needs at least {least} points (theta, r), got {th.size}",
                   f"give the radius at {least} or more angles")
    if not (np.all(np.isfinite(th)) and np.all(np.isfinite(r))):
        k = int(np.flatnonzero(~(np.isfinite(th) & np.isfinite(r)))[0])
        raise _err("bad_contour", f"{where(k)}: theta and r must be finite numbers", "fix the table")
    steps = np.diff(th)
    if np.any(steps <= 0):
        k = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise _err("contour_not_increasing", f"{where(k)}: theta = {th[k]:.6g} rad does not increase "
                   f"(previous {th[k - 1]:.6g} rad)", "list the points by increasing angle, one turn")
    if np.any(r <= 0):
        k = int(np.flatnonzero(r <= 0)[0])
        raise _err("contour_negative_radius", f"{where(k)}: r = {r[k]:.6g} m at theta = {th[k]:.6g} rad "
                   "must be > 0", "the contour must surround the roll's axis: every radius > 0")
    return th, r


@dataclass
class Contour:
    """A convex closed contour r(theta) [m] in the roll frame, a periodic C2 cubic spline.

    ``theta`` [rad]: strictly increasing angles spanning less than one turn (``theta[-1] <
    theta[0] + 2 pi``); the closing point ``theta[0] + 2 pi`` may be given as a last row with the
    first radius.  ``r`` [m]: positive radii.  ``source``: a name for messages (the table file)."""

    theta: np.ndarray
    r: np.ndarray
    source: str = "contour"
    lines: list | None = None              #: table line of each point (for messages)
    spline: CubicSpline = field(init=False, repr=False)
    joins: str = field(init=False, default="")   #: "C4"/"C2": how :meth:`from_arc` joined its closing part

    def __post_init__(self):
        th, r = _check_points(self.theta, self.r, self.source, self.lines)
        where = partial(_where, self.source, self.lines)
        span = th[-1] - th[0]
        scale = max(1.0, abs(th[0]))
        if span > TWO_PI + 1e-12 * scale:
            raise _err("contour_not_periodic", f"{self.source}: the angles span {span:.9g} rad, more than one turn",
                       "give one turn: theta[0] <= theta < theta[0] + 2*pi (a closing row at theta[0] + 2*pi)")
        if span >= TWO_PI - 1e-12 * scale:          # the closing row: it must repeat the first radius
            if abs(r[-1] - r[0]) > 1e-9 * max(r[0], 1e-300):
                raise _err("contour_not_periodic", f"{where(len(r) - 1)}: the closing point at theta[0] + 2*pi has "
                           f"r = {r[-1]:.9g} m, the first point r = {r[0]:.9g} m",
                           "a closed contour ends where it starts: repeat the first radius, or leave the row out")
            th, r = th[:-1], r[:-1]
            if len(th) < 3:
                raise _err("bad_contour", f"{self.source}: a contour needs at least 3 points over one turn",
                           "give the radius at three or more angles")
        gaps = np.diff(np.append(th, th[0] + TWO_PI))
        if gaps[-1] > 4 * gaps[:-1].max():          # an engaged arc, not a closed contour
            raise _err("contour_not_closed", f"{self.source}: the table covers theta = {th[0]:.6g} .. {th[-1]:.6g} "
                       f"rad only, a gap of {math.degrees(gaps[-1]):.4g} deg (its largest step is "
                       f"{math.degrees(gaps[:-1].max()):.3g} deg)",
                       "a roll's contour goes once round its axis: give the whole turn (an engaged arc "
                       "from a synthesis needs a convex closing part)")
        from scipy.interpolate import CubicSpline     # here: a scene without contours does not load scipy
        self.theta, self.r = th, r
        self.spline = CubicSpline(np.append(th, th[0] + TWO_PI), np.append(r, r[0]), bc_type="periodic")
        self._check_convex()
        self._tables()

    # -- construction -------------------------------------------------------------------------
    @classmethod
    def circle(cls, radius: float, n: int = 8) -> "Contour":
        """A circle of ``radius`` [m] about the axis (the spline of a constant is the constant)."""
        if not radius > 0:
            raise _err("contour_negative_radius", f"circle radius {radius!r} m must be > 0", "give a positive radius")
        return cls(np.linspace(0.0, TWO_PI, n, endpoint=False), np.full(n, float(radius)), f"circle r = {radius:g} m")

    @classmethod
    def from_function(cls, fun, n: int = 720, source: str = "") -> "Contour":
        """The contour through ``fun(theta)`` [m] at ``n`` equally spaced angles [rad] (a Python
        callable taking a numpy array; never a string)."""
        th = np.linspace(0.0, TWO_PI, n, endpoint=False)
        r = np.asarray(fun(th), dtype=float) * np.ones_like(th)
        return cls(th, r, source or getattr(fun, "__name__", "function"))

    @classmethod
    def from_support(cls, p, dp, n: int = 720, source: str = "support function") -> "Contour":
        """The contour whose support function is ``p(nu)`` [m] (``dp``: its derivative), sampled at
        ``n`` normal angles: the contact point is ``p e(nu) + p' e'(nu)`` (a band-curve synthesis
        result in polar form)."""
        nu = np.linspace(0.0, TWO_PI, n, endpoint=False)
        th, r = polar_from_support(p(nu), dp(nu), nu)
        k = int(np.argmin(th))
        return cls(np.roll(th, -k), np.roll(r, -k), source)

    @classmethod
    def from_arc(cls, theta, r, source: str = "arc", lines=None) -> "Contour":
        """A closed contour from an engaged arc (a synthesis result: theta [rad] increasing over less
        than a turn, r [m]): the arc's support function is continued over the normals it does not
        cover by :func:`close_arc` (C4 joins, else C2 joins with a :class:`ClosureWarning`; ``joins``
        says which); its convexity is checked like any contour's.  The arc's own points are kept; the
        closing part adds points at the arc's mean normal spacing."""
        th, rr = _check_points(theta, r, source, lines, least=4)
        if th[-1] - th[0] >= TWO_PI:
            raise _err("bad_contour", f"{source}: an arc spans less than a turn, this one "
                       f"{th[-1] - th[0]:.6g} rad", "give the engaged arc as the synthesis wrote it")
        from scipy.interpolate import CubicSpline
        arc = CubicSpline(th, rr)
        d1, d2 = arc(th, 1), arc(th, 2)
        den = rr * rr + 2 * d1 * d1 - rr * d2
        if np.any(den <= 0):
            k = int(np.flatnonzero(den <= 0)[0])
            raise _err("contour_not_convex", f"{source}: the arc is not convex at theta = {th[k]:.6g} rad",
                       "give a convex arc")
        nus = th - np.arctan2(d1, rr)                          # normals of the arc's points, increasing
        ps = rr * np.cos(th - nus)
        na, nb = float(nus[0]), float(nus[-1])
        gap = na + TWO_PI - nb
        n = max(64, int(math.ceil(gap / ((nb - na) / (len(th) - 1)))))
        closing = close_arc(nus, ps, n, source)
        tg, rg = polar_from_support(closing.p, closing.dp, closing.nu)
        tg = th[-1] + np.mod(tg - th[-1], TWO_PI)                    # after the arc's last angle
        c = cls(np.concatenate([th, tg]), np.concatenate([rr, rg]), source,
                None if lines is None else list(lines) + [f"closing point {k + 1}" for k in range(len(tg))])
        c.joins = closing.joins
        return c

    # -- evaluation ------------------------------------------------------------------------------
    def radius(self, theta, nu: int = 0):
        """r(theta) [m] or its ``nu``-th derivative [m/rad^nu], periodic."""
        return self.spline(self._base(theta), nu)

    def _base(self, theta):
        return self.theta[0] + np.mod(np.asarray(theta, dtype=float) - self.theta[0], TWO_PI)

    def curvature(self, theta):
        """Curvature kappa [1/m] of the contour at the polar angle theta [rad] (> 0: convex)."""
        r, d1, d2 = (self.radius(theta, k) for k in range(3))
        return (r * r + 2 * d1 * d1 - r * d2) / (r * r + d1 * d1) ** 1.5

    def normal_angle(self, theta):
        """Angle nu [rad] of the outward normal at the polar angle theta, unwrapped (nu - theta is small)."""
        return np.asarray(theta, dtype=float) - np.arctan2(self.radius(theta, 1), self.radius(theta))

    def _check_convex(self):
        """kappa > 0 on a grid of 16 points per spline interval (a cubic's curvature between them
        cannot dip far: the grid is refined where kappa comes near 0)."""
        knots = np.append(self.theta, self.theta[0] + TWO_PI)
        grid = np.concatenate([np.linspace(a, b, 16, endpoint=False) for a, b in zip(knots[:-1], knots[1:])])
        kappa = self.curvature(grid)
        k = int(np.argmin(kappa))
        if kappa[k] > 0:                          # refine around the smallest value
            lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
            fine = np.linspace(lo, hi, 201)
            kf = self.curvature(fine)
            if kf.min() < kappa[k]:
                grid, kappa, k = fine, kf, int(np.argmin(kf))
        self.kappa_min = float(kappa[k])
        if kappa[k] <= 0:
            th = float(np.mod(grid[k], TWO_PI))
            raise _err("contour_not_convex", f"{self.source}: the contour is not convex at theta = {th:.6g} rad "
                       f"({math.degrees(th):.4g} deg): curvature kappa = {kappa[k]:.6g} 1/m",
                       "a band roll's contour must be convex everywhere (r^2 + 2 r'^2 - r r'' > 0): smooth the "
                       "table or move the points near that angle outwards")

    def _tables(self, per_interval: int = 8):
        """Dense monotone table nu(theta) and cumulative arc length (Gauss-Legendre per sub-interval)."""
        knots = np.append(self.theta, self.theta[0] + TWO_PI)
        edges = np.concatenate([np.linspace(a, b, per_interval, endpoint=False) for a, b in zip(knots[:-1], knots[1:])]
                               + [knots[-1:]])
        x, wts = np.polynomial.legendre.leggauss(8)
        a, b = edges[:-1], edges[1:]
        pts = 0.5 * (a[:, None] + b[:, None]) + 0.5 * (b - a)[:, None] * x[None, :]
        speed = np.hypot(self.radius(pts), self.radius(pts, 1))
        seg = 0.5 * (b - a) * (speed * wts[None, :]).sum(axis=1)
        self._th = edges
        self._cum = np.concatenate([[0.0], np.cumsum(seg)])        # arc length from theta[0]
        self.perimeter = float(self._cum[-1])
        self._nu = self.normal_angle(edges)
        self._nu[-1] = self._nu[0] + TWO_PI

    def contact(self, nu):
        """Polar angle theta [rad] (unwrapped alongside nu) of the contact point whose outward normal
        has the angle nu [rad] (Newton from the dense table; nu(theta) is strictly increasing)."""
        nu = np.asarray(nu, dtype=float)
        turns = np.floor((nu - self._nu[0]) / TWO_PI)
        base = nu - TWO_PI * turns
        th = np.interp(base, self._nu, self._th)
        for _ in range(30):
            r, d1, d2 = (self.radius(th, k) for k in range(3))
            f = th - np.arctan2(d1, r) - base
            th = th - f * (r * r + d1 * d1) / (r * r + 2 * d1 * d1 - r * d2)
            if np.all(np.abs(f) < 1e-15):
                break
        return th + TWO_PI * turns

    def _arc_theta(self, theta):
        """Arc length [m] from theta[0] to theta (unwrapped)."""
        theta = np.asarray(theta, dtype=float)
        turns = np.floor((theta - self._th[0]) / TWO_PI)
        base = theta - TWO_PI * turns
        k = np.clip(np.searchsorted(self._th, base, side="right") - 1, 0, len(self._th) - 2)
        a = self._th[k]
        x, wts = np.polynomial.legendre.leggauss(12)
        pts = 0.5 * (a + base)[..., None] + 0.5 * (base - a)[..., None] * x
        part = 0.5 * (base - a) * (np.hypot(self.radius(pts), self.radius(pts, 1)) * wts).sum(axis=-1)
        return self._cum[k] + part + self.perimeter * turns

    def support(self, nu):
        """Support function p(nu) [m]: distance from the axis to the tangent line of normal nu."""
        th = self.contact(nu)
        return self.radius(th) * np.cos(th - np.asarray(nu, dtype=float))

    def arc(self, nu):
        """Arc length S(nu) [m] from the contact point of normal 0 to that of normal nu (unwrapped)."""
        return self._arc_theta(self.contact(nu)) - self._arc_theta(self.contact(0.0))

    # -- a band on the roll -------------------------------------------------------------------------
    def tangent_point(self, phi, gamma, side):
        """Global offset [m] of the contact point from the axis for the roll turned by phi [rad] and a
        span of inclination gamma [rad]; ``side`` = +1: the roll lies to the right of the span
        (seen from P1 to P2), -1: to the left (the half-plane choice, made once)."""
        th = self.contact(gamma + side * math.pi / 2 - np.asarray(phi, dtype=float)) + phi
        r = self.radius(th - phi)
        return np.stack([r * np.cos(th), r * np.sin(th)], axis=-1)

    def lever(self, phi, gamma, side):
        """Lever arm [m] of the band force about the axis: p(gamma + side*pi/2 - phi)."""
        return self.support(gamma + side * math.pi / 2 - np.asarray(phi, dtype=float))

    def wound(self, phi, gamma, side, w, phi0=0.0):
        """Band material [m] that left the roll into the span since the angle phi0 (``w`` = +1: a
        positive rotation pays out): w*(S(nu0) - S(nu)), nu = gamma + side*pi/2 - phi, unwrapped."""
        n0 = gamma + side * math.pi / 2
        return w * (self.arc(n0 - phi0) - self.arc(n0 - np.asarray(phi, dtype=float)))

    # -- the elements' smooth form ---------------------------------------------------------------------
    def series(self, tol: float = 1e-9, samples: int = 4096):
        """Trigonometric series of the support function: ``(a, b)`` with p(nu) = a[0] + sum_k a[k]
        cos(k nu) + b[k] sin(k nu), with the fewest harmonics K for which the left-out terms change
        p by at most ``tol`` [m] (measured at 2*samples angles).  ``series_error`` records the errors
        (p, S) [m] of the kept series against the spline itself at 512 other angles: S, whose series
        weighs the harmonics by k, follows the spline's knot-to-knot ripple less closely (about 5e-9 m
        for a 0.1 m ellipse from 720 points); it sets only the free length of the spans.
        ``contour_too_rough`` if more than :data:`MAX_HARMONICS` are needed."""
        nu = np.arange(samples) * TWO_PI / samples
        c = np.fft.rfft(self.support(nu)) / samples
        k = np.arange(len(c), dtype=float)

        def left_out(K):
            return float(np.max(np.abs(np.fft.irfft(np.where(k > K, c, 0.0), 2 * samples) * 2 * samples)))

        lo, hi = 0, min(MAX_HARMONICS, len(c) - 2)
        if left_out(hi) > tol:
            raise _err("contour_too_rough", f"{self.source}: the contour's support function needs more than "
                       f"{MAX_HARMONICS} harmonics to be represented to {tol:g} m",
                       "give a smoother contour (fewer, smoother points) or a larger tolerance")
        while lo < hi:                               # the fewest harmonics that meet tol
            mid = (lo + hi) // 2
            lo, hi = (mid + 1, hi) if left_out(mid) > tol else (lo, mid)
        a, b = 2 * c.real[:lo + 1], -2 * c.imag[:lo + 1]
        a[0] = c[0].real
        check = (np.arange(512) + 0.5) * TWO_PI / 512 + 0.1
        self.series_error = (float(np.max(np.abs(support_series(a, b, check) - self.support(check)))),
                             float(np.max(np.abs(arc_series(a, b, check) - self.arc(check)))))
        return a, b


HALF_PLANES = {"upper": (1, 1), "lower": (1, -1), "left": (0, -1), "right": (0, 1)}


def side_from_half_plane(gamma0: float, half_plane: str) -> int:
    """Ebert's half-plane choice (``enumHE``, Table 4.20 read consistently), made once at t = 0: the
    side (+1 or -1) whose contact normal ``gamma0 + side*pi/2`` points into the chosen half-plane
    about the roll's axis ('upper': y > 0, 'lower', 'left': x < 0, 'right').  A span along the
    half-plane's boundary (horizontal for upper/lower, vertical for left/right) is refused
    (``half_plane_ambiguous``): both contacts qualify there."""
    if half_plane not in HALF_PLANES:
        raise _err("bad_value", f"half-plane {half_plane!r} must be one of {', '.join(HALF_PLANES)}",
                   "upper, lower, left or right of the roll's axis")
    axis, sign = HALF_PLANES[half_plane]
    normal = gamma0 + math.pi / 2
    component = math.sin(normal) if axis else math.cos(normal)
    if abs(component) < 1e-9:
        raise _err("half_plane_ambiguous", f"a span of inclination {gamma0:.6g} rad touches the roll in the "
                   f"{half_plane} half-plane on both sides", "choose the half-plane across the span")
    return 1 if component * sign > 0 else -1


def support_series(a, b, nu):
    """p(nu) [m] from the series coefficients (numpy)."""
    k = np.arange(len(a))
    nu = np.asarray(nu, dtype=float)[..., None]
    return (a * np.cos(k * nu) + b * np.sin(k * nu)).sum(axis=-1)


def arc_series(a, b, nu):
    """S(nu) [m] from the series of p: S = integral of p + p'' from 0 (numpy)."""
    k = np.arange(1, len(a))
    nu = np.asarray(nu, dtype=float)
    terms = (a[1:] * (1 / k - k) * np.sin(k * nu[..., None]) + b[1:] * (k - 1 / k) * (np.cos(k * nu[..., None]) - 1))
    return a[0] * nu + terms.sum(axis=-1)


def _sym_series(a, b, nu, arc: bool, drop: float):
    """The series of p (or of S) as a sympy expression of ``nu``; terms below ``drop`` [m] left out."""
    out = sp.Float(a[0]) * nu if arc else sp.Float(a[0])
    for k in range(1, len(a)):
        ck, sk = (a[k] * (1 / k - k), b[k] * (k - 1 / k)) if arc else (a[k], b[k])
        if abs(ck) > drop:
            out += sp.Float(ck) * (sp.sin(k * nu) if arc else sp.cos(k * nu))
        if abs(sk) > drop:
            out += sp.Float(sk) * ((sp.cos(k * nu) - 1) if arc else sp.sin(k * nu))
    return out


class ClosureWarning(UserWarning):
    """An engaged arc was closed with C2 joins because the C4 closing part is not convex."""


@dataclass
class Closing:
    """The closing part of an engaged arc (:func:`close_arc`): normal angles ``nu`` [rad] (after the
    arc's last normal, before its first + 2 pi), support function ``p`` [m] and ``dp`` = p' [m/rad],
    and ``joins``: "C4" or "C2", the order to which p matches the arc at both ends."""

    nu: np.ndarray
    p: np.ndarray
    dp: np.ndarray
    joins: str


def _end_derivatives(x, y, at, order):
    """p and its first ``order`` derivatives at ``at`` from a degree-6 least-squares fit to the arc's
    points next to that end."""
    fit = np.polynomial.Polynomial.fit(x - at, y, min(6, len(x) - 1)).convert()
    return [float(fit.deriv(i)(0.0)) if i else float(fit(0.0)) for i in range(order + 1)]


def close_arc(nu, p, n: int, source: str = "arc", n_basis: int = 8) -> Closing:
    """The one closure of an engaged arc (used by ``arc: true`` tables and by the synthesis'
    ``close_contour``).  ``nu`` [rad]: the outward normal angles of the arc's points, increasing over
    less than a turn; ``p`` [m]: its support function there.  Over the ``n - 1`` normals of the gap
    (nu[-1], nu[0] + 2 pi) the support function is continued

    1. with C4 joins: the degree-9 polynomial matching p and its first four derivatives at both ends
       (from a degree-6 fit to the arc's last points) plus the bulge (c0 + c1 (s - 1/2)) s^5 (1 - s)^5
       that keeps p and the radius of curvature p + p'' furthest from 0.  Smooth joins let the
       elements' series get by with few harmonics.  Accepted when p + p'' > 0 and p > a tenth of the
       arc's smallest p;
    2. else with C2 joins, reported by a :class:`ClosureWarning` (never silently): the quintic
       matching p, p', p'' at both ends plus the smallest combination of ``n_basis`` bumps
       s^3 (1 - s)^3 s^j (a linear programme) with p and p + p'' >= half the smaller end value of p.
       It closes arcs whose C4 part would bulge through a cusp, at the price of more harmonics.

    Neither exists: ``ModelError`` ``contour_not_closed`` naming ``source``."""
    nu, p = np.asarray(nu, dtype=float), np.asarray(p, dtype=float)
    na, nb = float(nu[0]), float(nu[-1])
    gap = na + TWO_PI - nb
    if len(nu) < 4 or np.any(np.diff(nu) <= 0) or not gap > 0:
        raise _err("contour_not_closed", f"{source}: the arc's normals do not turn monotonically through less "
                   "than a full turn", "give one arc of a convex contour")
    m = max(8, min(40, len(nu) // 4))
    Db, Da = _end_derivatives(nu[-m:], p[-m:], nb, 4), _end_derivatives(nu[:m], p[:m], na, 4)
    sg = np.linspace(0.0, 1.0, n + 1)[1:-1]
    P = np.polynomial.polynomial

    def hermite(order):          # coefficients in s = (nu - nb)/gap matching Db at s = 0, Da at s = 1
        deg = 2 * order + 1
        rows, rhs = [], []
        for at, D in ((0.0, Db), (1.0, Da)):
            for i in range(order + 1):
                rows.append([math.perm(j, i) * at ** (j - i) if j >= i else 0.0 for j in range(deg + 1)])
                rhs.append(D[i] * gap ** i)
        return np.linalg.solve(np.array(rows), np.array(rhs))

    def values(coef, at):        # p, p', p'' [m, m/rad, m/rad^2]
        return (P.polyval(at, coef), P.polyval(at, P.polyder(coef)) / gap,
                P.polyval(at, P.polyder(coef, 2)) / gap ** 2)

    # 1. C4 joins and the best bulge over a coarse grid of (c0, c1)
    base, bump = hermite(4), P.polypow([0, 1, -1], 5)                  # s^5 (1 - s)^5, low order first
    tilt = P.polymul(bump, [-0.5, 1])

    def coef4(c0, c1):
        return P.polyadd(P.polyadd(base, c0 * bump), c1 * tilt)

    def margin(c, at):
        q, _, ddq = values(coef4(*c), at)
        return min(np.min(q), np.min(q + ddq))

    coarse, scale = np.linspace(0.0, 1.0, 201)[1:-1], 4 ** 5 * max(Da[0], Db[0])
    grid = [(c0 * scale, c1 * scale) for c0 in np.linspace(-1.0, 4.0, 41) for c1 in np.linspace(-8.0, 8.0, 41)]
    q, dq, ddq = values(coef4(*max(grid, key=lambda c: margin(c, coarse))), sg)
    bad = np.flatnonzero((q + ddq <= 0) | (q <= 0.1 * p.min()))
    if not len(bad):
        return Closing(nb + sg * gap, q, dq, "C4")
    k = bad[np.argmin(np.minimum(q[bad] + ddq[bad], q[bad]))]
    why = (f"at the normal angle {float(nb + sg[k] * gap):.4g} rad: distance p = {q[k]:.4g} m, radius of "
           f"curvature {q[k] + ddq[k]:.4g} m")
    # 2. C2 joins plus the smallest bumps (a linear programme)
    base2 = hermite(2)
    polys = [64 * np.polynomial.Polynomial([0, 0, 0, 1, -3, 3, -1]) * np.polynomial.Polynomial.basis(j)
             for j in range(n_basis)]                                   # 64 s^3 (1 - s)^3 s^j
    Bv = np.array([b(sg) for b in polys])
    Bd = np.array([b.deriv(1)(sg) / gap for b in polys])
    Bpp = np.array([b.deriv(2)(sg) / gap ** 2 for b in polys])
    q0, dq0, ddq0 = values(base2, sg)
    eps = 0.5 * min(Da[0], Db[0])                                       # the margin asked of p and p + p''
    A = np.vstack([np.c_[-Bv.T, Bv.T], np.c_[-(Bv + Bpp).T, (Bv + Bpp).T]])
    from scipy import optimize
    res = optimize.linprog(np.ones(2 * n_basis), A_ub=A, b_ub=np.r_[q0 - eps, q0 + ddq0 - eps],
                           bounds=[(0, None)] * (2 * n_basis), method="highs")
    if not res.success:
        raise _err("contour_not_closed", f"{source}: no convex closing part around the axis matches the arc's "
                   f"ends, neither with C4 joins ({why}) nor with C2 joins",
                   "synthesise a longer arc, or close the contour by hand (a whole turn in the table)")
    lam = res.x[:n_basis] - res.x[n_basis:]
    warnings.warn(f"{source}: the C4 closing part is not convex or passes the axis ({why}); closed with C2 joins "
                  "(the series needs more harmonics)", ClosureWarning, stacklevel=3)
    return Closing(nb + sg * gap, q0 + lam @ Bv, dq0 + lam @ Bd, "C2")


def polar_from_support(p, dp, nu):
    """Polar form (theta, r) of the contact points p e(nu) + p' e'(nu) of a support function."""
    x = p * np.cos(nu) - dp * np.sin(nu)
    y = p * np.sin(nu) + dp * np.cos(nu)
    return np.mod(np.arctan2(y, x), TWO_PI), np.hypot(x, y)


# -- the table format ----------------------------------------------------------------------------

def read_table(path, arc: bool = False) -> Contour:
    """A contour from a CSV table: a header line ``theta [rad], r [m]`` (any text not starting with a
    number), then one ``theta, r`` row per point, by increasing theta over one turn; ``#`` starts a
    comment line.  ``arc``: the table is an engaged arc (a synthesis result), completed by
    :meth:`Contour.from_arc`.  Errors name the file and the line."""
    theta, r, rows = _read_rows(path)
    if arc:
        return Contour.from_arc(theta, r, str(path), rows)
    return Contour(theta, r, str(path), rows)


def read_points(path) -> tuple[np.ndarray, np.ndarray]:
    """The points ``(theta [rad], r [m])`` of a contour table as they stand (a closed contour or an
    engaged arc, not completed, not interpolated), checked like :func:`read_table` checks them (at
    least 4 finite rows, theta increasing, r > 0); errors name the file and the line."""
    theta, r, rows = _read_rows(path)
    return _check_points(theta, r, str(path), rows, least=4)


def _read_rows(path) -> tuple[np.ndarray, np.ndarray, list]:
    """The rows of a contour table (the format of :func:`read_table`) and their line numbers."""
    path = Path(path)
    name = str(path)
    try:
        if path.exists() and not path.is_file():
            raise _err("bad_contour_table", f"{name} is not a regular file", "give the contour table's CSV file")
        size = os.path.getsize(path)
        if size > MAX_TABLE_BYTES:
            raise _err("bad_contour_table", f"{name}: the table is larger than {MAX_TABLE_BYTES // 1024} KiB",
                       "a contour table has a few thousand rows at most")
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise _err("no_file", f"cannot read the contour table {name}: {exc.strerror}",
                   "the path is relative to the netlist file") from None
    except UnicodeDecodeError:
        raise _err("bad_contour_table", f"{name}: the table is not UTF-8 text", "save it as CSV text") from None
    theta, r, lines = [], [], []
    for k, row in enumerate(csv.reader(text.splitlines()), start=1):
        cells = [c.strip() for c in row]
        if not cells or not any(cells) or cells[0].startswith("#"):
            continue
        try:
            values = [float(c) for c in cells if c]
        except ValueError:
            if not theta and not lines:             # the header line
                lines.append(None)
                continue
            raise _err("bad_contour_table", f"{name} line {k}: expected two numbers theta [rad], r [m]",
                       "one row per point: theta, r") from None
        if len(values) != 2:
            raise _err("bad_contour_table", f"{name} line {k}: expected two numbers theta [rad], r [m], got "
                       f"{len(values)}", "one row per point: theta, r")
        theta.append(values[0])
        r.append(values[1])
        lines.append(k)
        if len(theta) > MAX_ROWS:
            raise _err("bad_contour_table", f"{name}: more than {MAX_ROWS} rows", "a few thousand rows suffice")
    return np.array(theta), np.array(r), [n for n in lines if n is not None]


def write_table(path, theta, r, comment: str = "") -> None:
    """Write a contour table in the format :func:`read_table` reads (17 significant digits)."""
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(table_text(theta, r, comment))


def table_text(theta, r, comment: str = "") -> str:
    """The text of a contour table (:func:`write_table`): ``#`` comment lines, the header, one
    ``theta [rad], r [m]`` row per point written with 17 significant digits (read back exactly)."""
    lines = [f"# {line}" for line in comment.splitlines()] + ["theta [rad], r [m]"]
    lines += [f"{float(t)!r}, {float(v)!r}" for t, v in zip(theta, r)]
    return "\n".join(lines) + "\n"


def as_contour(value, arc: bool = False) -> Contour:
    """A Contour from a Contour, a table path (``arc``: an engaged arc to complete), a positive number
    (a circle of that radius [m]) or a Python callable r(theta)."""
    if isinstance(value, Contour):
        return value
    if isinstance(value, (str, os.PathLike)):
        return read_table(value, arc)
    if isinstance(value, (int, float, sp.Number)) and not isinstance(value, bool):
        return Contour.circle(float(value))
    if callable(value):
        return Contour.from_function(value)
    raise _err("bad_contour", f"contour {value!r} is not a table file, a number or a function",
               "give the contour table's file name (relative to the netlist)")


# -- elements ------------------------------------------------------------------------------------

_CONTOUR_DOC = ("contour table: CSV 'theta [rad], r [m]' (polar, roll frame, one turn, convex), a path relative "
                "to the netlist file (Python: also a Contour, a callable r(theta) or a number: a circle)")


def _curve(kind: str, sides: int, contour, arc, J, phi0, omega0, w, sides_of, tol, mu, r_pin, wrap, mu_c=None,
           stored=None):
    c = as_contour(contour, bool(arc))
    try:
        tol = float(tol)
    except TypeError:
        raise _err("bad_value", f"{kind}: tol = {tol} m must be a number", "e.g. 1e-9") from None
    for k, s in enumerate(sides_of, start=1):
        if s not in (1, -1):
            raise _err("bad_side", f"{kind}: side{k} = {s!r} must be +1 or -1",
                       "+1: the roll lies to the right of span k seen from its P1 to its P2, -1: to the left")
    a, b = c.series(tol)
    drop = tol / (4 * len(a))
    phi = sp.Symbol("phi")

    def nu(k, angle):
        # the offset as a float: with the symbol pi, sympy reasons on every term of the series
        return sp.Symbol(f"g{k}") + sp.Float(int(sides_of[k - 1]) * math.pi / 2) - angle

    def contact(k):
        lever = _sym_series(a, b, nu(k, phi), False, drop)
        wound = _sym_series(a, b, nu(k, sp.Symbol("phi0")), True, drop) - _sym_series(a, b, nu(k, phi), True, drop)
        return lever, wound

    reads = {f"g{k}": (f"e{k}.gamma", 0.0) for k in range(1, sides + 1)}
    net = _roll(kind, sides, None, J, phi0, omega0, w, mu, r_pin, wrap, contact=contact, reads=reads, mu_c=mu_c,
                stored=stored)
    for k in range(1, sides + 1):
        lever = _sym_series(a, b, nu(k, phi), False, drop)
        net.quantities[f"h{k}"] = Quantity(lambda V, e=lever: e.xreplace({s: V.param(s.name) for s in e.free_symbols}))
    net.contour, net.sides, net.w = c, tuple(int(s) for s in sides_of), int(w)
    return net


_CURVE_PARAMS = [Param("contour", "", _CONTOUR_DOC, kind="file"),
                 Param("arc", "", "the table is an engaged arc (a synthesis result): completed to a closed convex "
                       "contour by a closing part with C4 joins", False, "bool"),
                 Param("J", "kg*m^2", "moment of inertia about the axis", 1e-3, positive=True),
                 Param("phi0", "rad", "initial roll angle", 0.0),
                 Param("omega0", "rad/s", "initial angular velocity", 0.0),
                 Param("w", "-", "winding sense: +1: a positive rotation pays band out at e1 (winds in at e2)", 1.0)]
_SIDE = ("+1: the roll lies to the right of span {k} seen from the span's P1 to its P2 (contact normal at "
         "gamma + pi/2), -1: left; consistent: -w_k at a span's P1 end, +w_k at its P2 end (w_1 = w, w_2 = -w)")
_FRICTION = [Param("tol", "m", "largest error of the lever arm in the elements' smooth contour form (the wound length: "
                   "docs/belts.md)",
                   1e-9, positive=True),
             Param("mu", "-", "bearing friction coefficient (torque -mu*r_pin*radial load*sign(omega))", 0.0,
                   nonnegative=True),
             Param("r_pin", "m", "bearing pin radius", 0.004, nonnegative=True)]
_CURVE_QTY = _ROLL_QTY | {"h1": "m: lever arm of the band force at e1 (support function of the contour)"}


@element("curve_roll", "band roll with a convex curve contour (Ebert 4.4.5, corrected): no-slip winding, lever arm "
         "and wound length from the contour, inertia J, massless housing; bearing friction mu*r_pin*radial",
         {"e1": f"band port 1 ({_BAND})", "e2": f"band port 2 ({_BAND})",
          "drive": "1-D rotational port on the roll (angular velocity [rad/s], torque on the roll [N*m])"},
         _CURVE_PARAMS + [Param("side1", "-", _SIDE.format(k=1), 1.0), Param("side2", "-", _SIDE.format(k=2), 1.0)]
         + _FRICTION + [Param("wrap", "rad", "wrap angle for the radial load |F1 e1 + F2 e2| (angle between the "
                                             "spans' directions: pi - wrap)", math.pi, positive=True),
                        Param("mu_c", "-", "band-roll contact friction for the capstan monitor: the run reports "
                              "capstan_limit when one tension exceeds e^(mu_c*wrap) times the other; None: not "
                              "monitored", None, nonnegative=True)],
         _CURVE_QTY | {"F2": "N: band tension at e2", "h2": "m: lever arm of the band force at e2"})
def curve_roll(contour, arc, J, phi0, omega0, w, side1, side2, tol, mu, r_pin, wrap, mu_c):
    """Curve roll [contour in m, J in kg*m^2, angles in rad]."""
    return _curve("curve_roll", 2, contour, arc, J, phi0, omega0, w, (side1, side2), tol, mu, r_pin, wrap, mu_c=mu_c)


@element("curve_drum", "band drum with a convex curve contour (Ebert 4.4.5 derived): one band end fixed on it; "
         "winds band in or pays it out at e1 with the contour's lever arm (a band cam)",
         {"e1": f"band port ({_BAND})", "drive": "1-D rotational port on the drum"},
         _CURVE_PARAMS + [Param("side1", "-", _SIDE.format(k=1), 1.0)] + _FRICTION
         + [Param("stored", "m", "band stored on the drum at t = 0 (the length of contour it can pay out at e1); "
                  "paying out more stops the run with drum_paid_out; None: not monitored", None, positive=True)],
         _CURVE_QTY)
def curve_drum(contour, arc, J, phi0, omega0, w, side1, tol, mu, r_pin, stored):
    """Curve drum [contour in m, J in kg*m^2, angles in rad]."""
    return _curve("curve_drum", 1, contour, arc, J, phi0, omega0, w, (side1,), tol, mu, r_pin, None, stored=stored)


# -- static check --------------------------------------------------------------------------------

@register_check("curve_roll_side", "warning",
                "a curve roll's contact side disagrees with its winding sense and the span end it is joined to: "
                "the band would leave the contour on the other side, and the lever arms would be that side's")
def curve_roll_side(ctx):
    """At a span's P1 end the band leaves the contact along the span's direction, at its P2 end
    against it; with the port's winding sense w_k (w at e1, -w at e2) the consistent side is -w_k
    at a P1 end and +w_k at a P2 end (``docs/belts.md``, curve rolls)."""
    if ctx.scene is None:
        return
    ends = {prim: ext.rsplit(".", 1)[0] for ext, prim in ctx.flat.external_ports.items()
            if ext.endswith(".l") and ctx.flat.bundles.get(ext.rsplit(".", 1)[0]) == "band"}
    for node in ctx.flat.nodes:
        refs = [ends[p] for p in node.ports if p in ends]
        if node.origin != "connection" or len(refs) != 2:
            continue
        for roll_ref, span_ref in (refs, refs[::-1]):
            (roll, port), (span, end) = roll_ref.split("."), span_ref.split(".")
            net = ctx.scene.network.children.get(roll)
            if ctx.flat.elements.get(span) != "band" or not hasattr(net, "sides"):
                continue
            k = int(port[1:])
            wk = net.w if k == 1 else -net.w
            want = -wk if end == "e1" else wk
            if net.sides[k - 1] != want:
                yield Diagnostic("curve_roll_side",
                                 f"{roll}.{port} is joined to the {'P1' if end == 'e1' else 'P2'} end of {span}: "
                                 f"with w = {net.w:+d} the band leaves the contour along that span only with "
                                 f"side{k} = {want:+d}, not {net.sides[k - 1]:+d} (the other side's lever arms)",
                                 elements=[roll, span],
                                 fix=f"set side{k}: {want} on {roll}, or reverse its winding sense w")
