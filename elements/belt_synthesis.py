"""Band-curve synthesis, assessment and spring-band balancing after Ebert (2015, ch. 4.3, 5, 6).

Python functions (numpy/scipy), not network elements.  All lengths in m, angles in rad, torques in
N*m, spring rates in N/m.  The workflow is Ebert's two-phase kinematic inversion:

1. a **structure** computes, for every drive angle phi of the cam, the path of a material point of
   the band (the *trace*) in the frame: :class:`DBSD` (band from the cam to a frame-pivoted spring
   or take-off nozzle, Ebert 4.3.3) or :class:`DBBD` (band from the cam to a frame-pivoted circular
   roll, Ebert 4.3.2);
2. :func:`band_curve` (Ebert's ``Bandkurve``, 4.3.4) turns the trace back into the cam frame (the
   *involute*, 4.50/4.51) and takes its evolute (3.7/3.8): the band-curve contour.

:func:`assess` is the chapter-5 assessment (free band length, its derivative's sign S_Bf, the
practical recommendations as :class:`Finding` objects with codes); :func:`synthesise_contour`
runs structure -> band curve -> assessment and writes the contour as a CSV table ``theta [rad],
r [m]`` (polar, cam frame).  :func:`spring_band_balance` is chapter 6 with the closed-form
quadrature of the spring travel, :func:`spring_band_analysis` the independent check: the torque a
spring band exerts through a contour table, found by the tangent from the spring pivot;
:func:`close_contour` completes a synthesised arc to the closed convex contour a ``curve_drum``
carries; :class:`CabinetDoor` is the worked example (Ebert 7.2.1).

Conventions (ours, where Ebert's printed ones contradict each other; see docs/belts.md):

* The transfer function of :class:`DBSD` is the band travel x(phi) [m] onto the cam (= spring
  extension, or the band drawn through the nozzle), the lever arm is its derivative h = x'
  (Ebert 4.49).  ``K = +1``: for h > 0 the foot 23 of the perpendicular from the cam pivot P1 onto
  the band line lies left of the frame line P1 -> P2 and a positive (counter-clockwise) cam angle
  winds band on; ``K = -1`` is the mirror image about the frame line (the cam turns by -phi).
* The transfer function of :class:`DBBD` is the roll angle psi(phi) [rad]; the ratio is
  i = psi' = omega_roll/omega_cam and the lever arm on the cam is |i|*r4 (Ebert 4.2 corrected,
  erratum E11).  ``K = +1``: the roll's contact point 34 lies left of the frame line P1 -> P2.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
from scipy import interpolate, optimize

from multipole import ModelError

from .belt_contour import close_arc, read_points as read_contour_table, write_table   # the one table reader/writer

__all__ = ["Transfer", "Trace", "DBSD", "DBBD", "DBDS", "DBDD", "attached_trace", "BandCurve", "band_curve",
           "evolute", "Finding",
           "Assessment", "assess", "Synthesis", "synthesise_contour", "write_contour_table",
           "read_contour_table", "Balance", "spring_band_balance", "SpringBandAnalysis",
           "spring_band_analysis", "CabinetDoor", "Band", "SynthesisWarning", "close_contour"]


class SynthesisWarning(UserWarning):
    """A recommendation of Ebert 5.3 that a synthesised band curve does not meet (a
    :class:`Finding` of severity "warning", issued by :func:`synthesise_contour`)."""


def _rot(a: np.ndarray) -> np.ndarray:
    """Rotation matrices R(a), shape (n, 2, 2)."""
    c, s = np.cos(a), np.sin(a)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _perp(v: np.ndarray) -> np.ndarray:
    """J v: v turned by +90 degrees (the left normal)."""
    return np.stack([-v[..., 1], v[..., 0]], -1)


# -- transfer functions ------------------------------------------------------------------------------

class Transfer:
    """A transfer function f(phi) with its first three derivatives.

    ``Transfer(f, df, ddf, dddf)`` from callables (each maps an array of angles [rad] to values);
    a missing third derivative is taken by central differences of ``ddf`` (it only enters terms that
    cancel in the evolute, see :func:`band_curve`).  :meth:`from_table` builds it from a table.
    """

    def __init__(self, f: Callable, df: Callable, ddf: Callable, dddf: Callable | None = None):
        self._f = (f, df, ddf, dddf)

    @classmethod
    def from_table(cls, phi: Sequence[float], values: Sequence[float]) -> "Transfer":
        """A quintic interpolating spline through ``(phi [rad], values)`` (C4: its derivatives up to
        the third are continuous).  ``phi`` must increase strictly; at least 6 points."""
        phi, values = np.asarray(phi, float), np.asarray(values, float)
        if phi.ndim != 1 or phi.shape != values.shape or len(phi) < 6:
            raise ModelError("bad_table", "transfer table: phi and values must be two equal 1-D columns "
                             "of at least 6 points", "give phi [rad] and the values, one per row")
        if not np.all(np.isfinite(phi)) or not np.all(np.isfinite(values)) or np.any(np.diff(phi) <= 0):
            raise ModelError("bad_table", "transfer table: phi must increase strictly and all values be "
                             "finite", "sort the table by phi and remove repeated angles")
        spl = interpolate.make_interp_spline(phi, values, k=5)
        return cls(spl, spl.derivative(1), spl.derivative(2), spl.derivative(3))

    def __call__(self, phi, order: int = 0):
        """The ``order``-th derivative (0..3) at ``phi``."""
        phi = np.asarray(phi, float)
        f = self._f[order]
        if f is None:   # third derivative by central differences of the second
            d = 1e-4
            return (np.asarray(self._f[2](phi + d), float) - np.asarray(self._f[2](phi - d), float)) / (2 * d)
        return np.broadcast_to(np.asarray(f(phi), float), phi.shape).copy()


# -- structures (phase 1: the trace) -----------------------------------------------------------------

@dataclass
class Trace:
    """The path of a band material point over the drive angle (output of a structure).

    ``phi`` drive angles [rad]; ``cam`` the cam's rotation angle (K*phi for a mirrored DB~SD) and
    ``dcam`` its derivative; ``p``, ``dp``, ``ddp`` the trace point and its first two phi-derivatives
    in the frame [m, m/rad, m/rad^2] (shape (n, 2)); ``foot`` the foot 23 of the perpendicular from
    the cam pivot onto the band line; ``lever`` the signed lever arm on the cam [m] (the band travel
    rate onto the cam per radian); ``gamma`` the band direction (toward the cam for DB~SD, toward
    the roll for DB~BD) [rad]; ``pivot`` the cam pivot P1."""

    phi: np.ndarray
    cam: np.ndarray
    dcam: float
    p: np.ndarray
    dp: np.ndarray
    ddp: np.ndarray
    foot: np.ndarray
    lever: np.ndarray
    gamma: np.ndarray
    pivot: np.ndarray
    contact_far: np.ndarray | None = None   # DB~BD: the roll's tangent point 34


def _frame(p1, p2, what: str):
    p1, p2 = np.asarray(p1, float), np.asarray(p2, float)
    l1 = float(np.hypot(*(p2 - p1)))     # Ebert (4.38) with the corrected (4.37): H1^2 + H2^2 (E12)
    if not l1 > 0:
        raise ModelError("bad_length", f"{what}: the pivots P1 and P2 coincide",
                         "place the cam pivot P1 and the other pivot P2 apart")
    return p1, p2, l1


@dataclass
class DBSD:
    """Structure DB~SD (Ebert 4.3.3): a band from the cam (pivot ``p1``) to a spring or take-off
    nozzle pivoted in the frame at ``p2`` [m].  The band line passes through P2 at the distance
    |h| from P1.  ``s0`` [m]: distance from P2 to the traced band point at the first angle (the
    spring length there; any value gives the same contour).  ``K``: +1 or -1 (see the module).

    ``p2 = None`` and ``gamma`` [rad]: the band keeps the direction gamma (pointing from the spring
    toward the cam), as when the spring is a slider on a guide parallel to the band or P2 is far
    away (the limit l1 -> infinity); ``s0`` is then the distance of the traced point from the
    foot 23 along the band."""

    p1: Sequence[float]
    p2: Sequence[float] | None
    K: int = 1
    s0: float | None = None
    gamma: float | None = None

    def trace(self, phi, x: Transfer) -> Trace:
        """The trace of the band point for the band travel ``x(phi)`` [m] (lever h = x')."""
        if self.K not in (1, -1):
            raise ModelError("bad_assembly_mode", f"DB~SD: K = {self.K!r} must be +1 or -1",
                             "K = +1: the foot 23 lies left of P1 -> P2 for h > 0")
        phi = np.asarray(phi, float)
        xs, h, dh, ddh = (x(phi, k) for k in range(4))
        K = self.K
        if self.p2 is None:                               # the band keeps its direction
            if self.gamma is None:
                raise ModelError("bad_value", "DB~SD: give the spring pivot p2 or the band direction gamma",
                                 "p2 = (x, y) [m], or p2 = None and gamma [rad] for a guided band")
            p1 = np.asarray(self.p1, float)
            e = np.broadcast_to([math.cos(self.gamma), math.sin(self.gamma)], (len(phi), 2))
            n = _perp(e)
            foot = p1 - (K * h)[:, None] * n
            s0 = 0.1 + 2 * float(np.ptp(xs)) if self.s0 is None else float(self.s0)
            s = s0 - (xs - xs[0])                         # distance from 23 back to the point
            p = foot - s[:, None] * e
            dp = -(K * dh)[:, None] * n + h[:, None] * e
            ddp = -(K * ddh)[:, None] * n + dh[:, None] * e
            return Trace(phi, K * phi, float(K), p, dp, ddp, foot, h, np.full(len(phi), float(self.gamma)), p1)
        p1, p2, l1 = _frame(self.p1, self.p2, "DB~SD")
        if np.any(np.abs(h) >= l1):
            k = int(np.argmax(np.abs(h)))
            raise ModelError("bad_value", f"DB~SD: lever arm |h| = {abs(h[k]):.6g} m at phi = {phi[k]:.6g} rad "
                             f"reaches the pivot distance {l1:.6g} m (Ebert 4.39 has no solution)",
                             "move the spring pivot P2 further from the cam pivot or limit h")
        l2 = np.sqrt(l1 * l1 - h * h)                      # (4.39): distance P2 - 23
        m = (p1 - p2) / l1                                 # unit P2 -> P1
        gamma = math.atan2(m[1], m[0]) - np.arcsin(K * h / l1)   # band direction P2 -> 23 (4.46)
        dg = -K * dh / l2
        ddg = -K * (ddh / l2 + h * dh * dh / l2 ** 3)
        e = np.stack([np.cos(gamma), np.sin(gamma)], -1)
        n = _perp(e)
        foot = p1 - (K * h)[:, None] * n                   # (4.44)/(4.45): 23, |23 - P1| = |h|
        s0 = 0.5 * l2[0] if self.s0 is None else float(self.s0)
        s = s0 + xs - xs[0]                                # (4.47)/(4.48) with s' = h (see docs)
        p = p2 + s[:, None] * e
        dp = h[:, None] * e + (s * dg)[:, None] * n
        ddp = (dh - s * dg * dg)[:, None] * e + (2 * h * dg + s * ddg)[:, None] * n
        return Trace(phi, K * phi, float(K), p, dp, ddp, foot, h, gamma, p1)


@dataclass
class DBBD:
    """Structure DB~BD with a circular roll (Ebert 4.3.2): a band from the cam (pivot ``p1``) to a
    roll of radius ``r4`` [m] turning about ``p2``.  ``K = +1``: the roll's contact point 34 lies
    left of the frame line P1 -> P2.  ``s0`` [m]: free length from 34 to the traced band point at
    the first angle (any value gives the same contour)."""

    p1: Sequence[float]
    p2: Sequence[float]
    r4: float
    K: int = 1
    s0: float | None = None

    def trace(self, phi, psi: Transfer) -> Trace:
        """The trace of the band point for the roll angle ``psi(phi)`` [rad] (ratio i = psi')."""
        if self.K not in (1, -1):
            raise ModelError("bad_assembly_mode", f"DB~BD: K = {self.K!r} must be +1 or -1",
                             "K = +1: the roll's contact point lies left of P1 -> P2")
        if not self.r4 > 0:
            raise ModelError("bad_value", f"DB~BD: roll radius r4 = {self.r4!r} m must be > 0",
                             "give the roll radius in metres")
        phi = np.asarray(phi, float)
        p1, p2, l1 = _frame(self.p1, self.p2, "DB~BD")
        ps, i, di, ddi = (psi(phi, k) for k in range(4))
        d2 = -self.K * self.r4                     # signed distance of P2 from the band line
        q = (1.0 - i) * d2 / l1                    # sin(beta - gamma): n.(P2 - P1) = (1 - i) d2
        if np.any(np.abs(q) >= 1):
            k = int(np.argmax(np.abs(q)))
            raise ModelError("bad_value", f"DB~BD: ratio i = {i[k]:.6g} at phi = {phi[k]:.6g} rad needs a band "
                             f"line the pivots {l1:.6g} m apart cannot carry (|1 - i| r4 >= l1)",
                             "increase the pivot distance or reduce |1 - i| * r4")
        beta = math.atan2(*(p2 - p1)[::-1])
        gamma = beta - np.arcsin(q)                # band direction 23 -> 34 (4.23)
        cq = np.sqrt(1 - q * q)
        dg = di * d2 / (l1 * cq)
        ddg = (ddi * d2 / l1 - q * dg * dg) / cq   # differentiate -cos(beta - gamma) g' = -i' d2/l1
        u = np.stack([np.cos(gamma), np.sin(gamma)], -1)
        n = _perp(u)
        c34 = p2 - d2 * n                          # tangent point on the roll, |34 - P2| = r4 (E8)
        foot = p1 - (i * d2)[:, None] * n          # 23: |23 - P1| = |i| r4 (E11)
        # band leaving the roll into the span: l_r = K r4 (dpsi - dgamma) (Ebert 4.24; 3.4 corrected)
        s0 = 0.5 * float(np.hypot(*(c34[0] - foot[0]))) if self.s0 is None else float(self.s0)
        s = s0 + self.K * self.r4 * ((ps - ps[0]) - (gamma - gamma[0]))
        ds = self.K * self.r4 * (i - dg)
        dds = self.K * self.r4 * (di - ddg)
        p = c34 - s[:, None] * u                   # (4.27)/(4.28)
        # derivatives: c34' = d2 g' u, c34'' = d2 (g'' u + g'^2 n); u' = g' n, u'' = g'' n - g'^2 u
        dp = (d2 * dg - ds)[:, None] * u - (s * dg)[:, None] * n
        ddp = (d2 * ddg - dds + s * dg * dg)[:, None] * u + (d2 * dg * dg - 2 * ds * dg - s * ddg)[:, None] * n
        return Trace(phi, phi, 1.0, p, dp, ddp, foot, i * self.r4, gamma, p1, c34)


def attached_trace(phi, p1, p, dp, ddp, K: int = 1) -> Trace:
    """The trace of a band whose end is tied by a revolute joint to a point of a linkage (Ebert
    4.3.1: DB~DD, DB~DS and every other structure without a band element of its own).  The trace
    is the joint's path itself: ``p``, ``dp``, ``ddp`` its position in the frame and its first two
    derivatives over the drive angle ``phi`` [m, m/rad, m/rad^2] (shape (n, 2)); the cam (pivot
    ``p1``) turns by K*phi.  The band line is the involute's normal through the joint, so the foot
    23, the band direction gamma (from the joint toward the cam) and the lever arm h (the band
    travel onto the cam per radian, the joint's velocity along the band) follow from the trace."""
    if K not in (1, -1):
        raise ModelError("bad_assembly_mode", f"band on a linkage: K = {K!r} must be +1 or -1",
                         "K = +1: the cam turns counter-clockwise as phi increases")
    phi = np.asarray(phi, float)
    p1 = np.asarray(p1, float)
    p, dp, ddp = (np.asarray(a, float) for a in (p, dp, ddp))
    d = p - p1
    v = dp - K * _perp(d)                      # the joint's velocity seen from the cam (frame axes)
    a = ddp - 2 * K * _perp(dp) - d            # its acceleration (K^2 = 1)
    # the centre of curvature of the relative path lies toward the cam: the band points there
    n = _perp(v) * np.sign(_cross(v, a))[:, None]
    g = n / np.linalg.norm(n, axis=1)[:, None]
    foot = p + np.einsum("ij,ij->i", p1 - p, g)[:, None] * g
    lever = np.einsum("ij,ij->i", dp, g)
    gamma = np.unwrap(np.arctan2(g[:, 1], g[:, 0]))
    return Trace(phi, K * phi, float(K), p, dp, ddp, foot, lever, gamma, p1)


@dataclass
class DBDS:
    """Structure DB~DS (Ebert 4.3.1, 7.2.2): the band pulls a slider along a guide in the frame.
    The band is tied to the slider's joint, which runs on the line through ``guide_point`` [m] of
    direction ``guide_angle`` [rad]; the transfer function is the joint's position x(phi) [m] along
    the guide from ``guide_point``.  The cam (pivot ``p1``) turns by K*phi (K = +1:
    counter-clockwise).  Ebert's 7.2.2: the guide passes through the cam pivot (the default)."""

    p1: Sequence[float]
    guide_point: Sequence[float] | None = None
    guide_angle: float = 0.0
    K: int = 1

    def trace(self, phi, x: Transfer) -> Trace:
        """The trace of the slider's joint for the slider position ``x(phi)`` [m]."""
        phi = np.asarray(phi, float)
        o = np.asarray(self.p1 if self.guide_point is None else self.guide_point, float)
        e = np.array([math.cos(self.guide_angle), math.sin(self.guide_angle)])
        xs, dx, ddx = (x(phi, k) for k in range(3))
        return attached_trace(phi, self.p1, o + xs[:, None] * e, dx[:, None] * e, ddx[:, None] * e, self.K)


@dataclass
class DBDD:
    """Structure DB~DD (Ebert 4.3.1): the band pulls a rocker of length ``length`` [m] pivoted in
    the frame at ``p2`` [m]; the transfer function is the rocker angle psi(phi) [rad] (from the
    x axis, counter-clockwise).  The cam (pivot ``p1``) turns by K*phi."""

    p1: Sequence[float]
    p2: Sequence[float]
    length: float
    K: int = 1

    def trace(self, phi, psi: Transfer) -> Trace:
        """The trace of the rocker's band joint for the rocker angle ``psi(phi)`` [rad]."""
        if not self.length > 0:
            raise ModelError("bad_length", f"DB~DD: rocker length {self.length!r} m must be > 0",
                             "give the distance from the rocker pivot to the band joint in metres")
        phi = np.asarray(phi, float)
        ps, dps, ddps = (psi(phi, k) for k in range(3))
        u = self.length * np.stack([np.cos(ps), np.sin(ps)], -1)
        return attached_trace(phi, self.p1, np.asarray(self.p2, float) + u, dps[:, None] * _perp(u),
                              ddps[:, None] * _perp(u) - (dps * dps)[:, None] * u, self.K)


# -- phase 2: the band curve -------------------------------------------------------------------------

def evolute(e: np.ndarray, de: np.ndarray, dde: np.ndarray):
    """Evolute of a plane curve e(phi) from its first two derivatives (Ebert 3.7/3.8).

    Returns ``(u, Z)``: the centres of curvature u (shape (n, 2)) and Z = x_e' y_e'' - y_e' x_e''
    (Ebert's limit function GF_1, 5.7); where Z = 0 the evolute is at infinity (entries inf)."""
    Z = _cross(de, dde)
    q = np.einsum("ij,ij->i", de, de)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = q / Z
    u = np.stack([e[:, 0] - de[:, 1] * f, e[:, 1] + de[:, 0] * f], -1)
    return u, Z


@dataclass
class BandCurve:
    """Output of :func:`band_curve`, all in the cam frame (origin at the cam pivot, orientation of
    the cam at angle 0): ``phi`` [rad]; ``involute`` the trace point e and ``d_involute`` e'
    [m, m/rad]; ``contour`` the evolute u = the band-curve contour [m]; ``Z`` (GF_1);
    ``free_length`` l_Bf = |e - u| [m] (5.3); ``band_angle`` the direction of the band in the cam
    frame [rad] (unwrapped)."""

    phi: np.ndarray
    involute: np.ndarray
    d_involute: np.ndarray
    contour: np.ndarray
    Z: np.ndarray
    free_length: np.ndarray
    band_angle: np.ndarray
    trace: Trace


def band_curve(trace: Trace) -> BandCurve:
    """Ebert's ``Bandkurve`` (4.3.4): the trace turned back by the cam angle about the pivot
    (4.50/4.51: the involute, with its phi-derivatives by the chain rule) and its evolute (3.7/3.8),
    the band-curve contour.  Terms of the trace's second derivative along the involute's tangent
    cancel in the evolute, so only the band travel and the lever arm's first derivative matter."""
    a, da = trace.cam, trace.dcam
    d = trace.p - trace.pivot
    Rm = _rot(-a)
    e = np.einsum("nij,nj->ni", Rm, d)
    de = np.einsum("nij,nj->ni", Rm, trace.dp - da * _perp(d))
    dde = np.einsum("nij,nj->ni", Rm, trace.ddp - 2 * da * _perp(trace.dp) - da * da * d)
    u, Z = evolute(e, de, dde)
    band = np.unwrap(np.arctan2(de[:, 0], -de[:, 1]))   # the band is normal to e'
    return BandCurve(trace.phi, e, de, u, Z, np.hypot(*(e - u).T), band, trace)


# -- chapter 5: assessment ---------------------------------------------------------------------------

@dataclass(frozen=True)
class Finding:
    """One result of the assessment: ``code``, ``severity`` ("error": the contour cannot be made;
    "warning": a recommendation of Ebert 5.3 not met), a one-line ``message`` and a ``fix``."""

    code: str
    severity: str
    message: str
    fix: str

    def __str__(self) -> str:
        return f"{self.severity}[{self.code}] {self.message} (fix: {self.fix})"


@dataclass
class Assessment:
    """Chapter-5 assessment of a band curve.  Arrays over the drive angle: ``free_length`` l_Bf
    [m] (5.3), ``d_free_length`` dl_Bf/dphi [m/rad] (5.10), ``S_Bf`` its sign (5.11), ``radius`` the
    distance a of the contact point from the pivot [m] (5.12), ``lever`` h [m] (5.13: the distance
    of the pivot from the band line, erratum E14), ``contour_radius`` the contour's radius of
    curvature rho = |dl_Bf/dphi| / |d(band angle)/dphi| [m]; ``force`` F_B = T/h [N] and
    ``stress`` sigma_z + sigma_b [Pa] (5.16-5.18) when a torque and a band are given.
    ``producible``: S_Bf never changes sign; ``findings``: the :class:`Finding` list."""

    free_length: np.ndarray
    d_free_length: np.ndarray
    S_Bf: np.ndarray
    radius: np.ndarray
    lever: np.ndarray
    contour_radius: np.ndarray
    producible: bool
    findings: list = field(default_factory=list)
    force: np.ndarray | None = None
    stress: np.ndarray | None = None

    @property
    def max_radius(self) -> float:
        """Largest cam radius over the motion [m] (5.12: the installation space)."""
        return float(np.max(self.radius))


@dataclass(frozen=True)
class Band:
    """A band's cross-section for the stress check (Ebert 5.16-5.18): thickness ``t`` [m], width
    ``b`` [m], Young's modulus ``E`` [Pa], allowed stress ``sigma_allowed`` [Pa]."""

    t: float
    b: float
    E: float
    sigma_allowed: float


def _sign_changes(s: np.ndarray) -> np.ndarray:
    """Indices k where the sign of s changes between k and k+1 (zeros skipped)."""
    idx = np.flatnonzero(s != 0)
    flips = idx[:-1][np.diff(np.sign(s[idx])) != 0]
    return flips


def assess(curve: BandCurve, transfer: Transfer | None = None, *, torque: Callable | None = None,
           band: Band | None = None, max_radius: float | None = None) -> Assessment:
    """Assess a band curve (Ebert ch. 5).  The contour exists when the sign S_Bf of the free
    length's derivative stays constant over the motion (5.2); the recommendations of 5.3 become
    findings: ``transfer_not_smooth`` (the transfer function's second derivative jumps, 5.3.1),
    ``transfer_dwell`` (lever arm or ratio zero: a dwell, 5.3.1), ``contour_not_producible`` (S_Bf
    or Z change sign, 5.3.2; severity error), ``cam_too_large`` (largest radius above
    ``max_radius`` [m], 5.3.3), ``band_overstressed`` (sigma_z + sigma_b above the allowed stress
    for ``torque(phi)`` [N*m] and ``band``, 5.3.4-5).  The drive angles must be a fine grid."""
    phi = curve.phi
    lbf = curve.free_length
    dl = np.gradient(lbf, phi, edge_order=2)
    S = np.sign(dl)
    findings = []
    flips = _sign_changes(S)
    zflips = _sign_changes(np.sign(curve.Z))
    bad = np.union1d(flips, zflips)
    if len(bad):
        where = ", ".join(f"{0.5 * (phi[k] + phi[k + 1]):.4g}" for k in bad[:5])
        findings.append(Finding("contour_not_producible", "error",
                                f"the free band length's derivative dl_Bf/dphi changes sign at phi = {where} rad "
                                "(Ebert 5.2: the contour has a cusp or splits there)",
                                "change the transfer function, the pivots or the mounting side K"))
    if transfer is not None:
        d1, d2 = transfer(phi, 1), transfer(phi, 2)
        scale = max(float(np.max(np.abs(d1))), 1e-300)
        zero = np.flatnonzero(np.abs(d1) <= 1e-9 * scale)
        if len(zero) or len(_sign_changes(np.sign(d1))):
            k = int(zero[0]) if len(zero) else int(_sign_changes(np.sign(d1))[0])
            findings.append(Finding("transfer_dwell", "warning",
                                    f"the transfer function's first derivative is zero at phi = {phi[k]:.4g} rad "
                                    "(a dwell or reversal: the band passes through the cam pivot, Ebert 5.3)",
                                    "avoid dwells; a band mechanism needs a lever arm that does not vanish"))
        # a jump of f'' is one step between neighbouring samples far larger than the steps on
        # either side of it (a smooth f'' changes by about f''' dphi at every step)
        step = np.abs(np.diff(d2))
        side = np.maximum(np.r_[step[1:2], step[:-1]], np.r_[step[1:], step[-2:-1]]) if len(step) > 2 else step
        jumps = np.flatnonzero(step > 10 * side + 1e-9 * max(float(np.max(np.abs(d2))), 1e-300))
        if len(jumps):
            k = int(jumps[0])
            findings.append(Finding("transfer_not_smooth", "warning",
                                    f"the transfer function's second derivative jumps near phi = {phi[k]:.4g} rad "
                                    "(Ebert 5.3: it must be continuous up to the second derivative)",
                                    "use a C2 motion law (e.g. a 5th-degree polynomial transition)"))
    radius = np.hypot(*curve.contour.T)
    if max_radius is not None and np.max(radius) > max_radius:
        k = int(np.argmax(radius))
        findings.append(Finding("cam_too_large", "warning",
                                f"the cam radius reaches {radius[k]:.4g} m at phi = {phi[k]:.4g} rad, above the "
                                f"installation space {max_radius:.4g} m (Ebert 5.12)",
                                "limit the lever arm or move the pivots"))
    lever = np.abs(curve.trace.lever)
    dband = np.gradient(curve.band_angle, phi, edge_order=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.abs(dl) / np.abs(dband)
    force = stress = None
    if torque is not None:
        with np.errstate(divide="ignore"):
            force = np.abs(np.asarray(torque(phi), float)) / lever
        if band is not None:
            with np.errstate(divide="ignore"):
                stress = force / (band.t * band.b) + band.E * band.t / (2 * rho)
            if np.any(stress > band.sigma_allowed):
                k = int(np.argmax(stress))
                findings.append(Finding("band_overstressed", "warning",
                                        f"tension plus bending stress {stress[k]:.4g} Pa at phi = {phi[k]:.4g} rad "
                                        f"exceeds the allowed {band.sigma_allowed:.4g} Pa (Ebert 5.16-5.18)",
                                        "use a thinner or wider band, or a larger lever arm"))
    return Assessment(lbf, dl, S, radius, lever, rho, not len(bad), findings, force, stress)


# -- the contour table -------------------------------------------------------------------------------

def write_contour_table(path, contour: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Write a contour (cam frame, shape (n, 2) [m]) as the polar CSV table ``theta [rad], r [m]``
    that ``curve_roll`` reads (header line, then one row per point, theta increasing and unwrapped;
    written by ``belt_contour.write_table``).  The points are
    reordered so that theta increases; the polar angle must be monotonic along the contour (the
    pivot inside the convex contour).  Returns ``(theta, r)``."""
    contour = np.asarray(contour, float)
    theta = np.unwrap(np.arctan2(contour[:, 1], contour[:, 0]))
    r = np.hypot(*contour.T)
    if theta[-1] < theta[0]:
        theta, r = theta[::-1], r[::-1]
    if np.any(np.diff(theta) <= 0) or not np.all(np.isfinite(r)):
        raise ModelError("contour_not_polar", f"{path}: the contour's polar angle about the cam pivot is not "
                         "monotonic (the pivot lies outside the contour or the contour is broken)",
                         "assess the contour first; a producible band curve around its pivot is polar")
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    write_table(tmp, theta, r)          # the curve rolls' table format (elements/belt_contour.py)
    tmp.replace(path)
    return theta, r


def close_contour(curve: BandCurve) -> np.ndarray:
    """The synthesised arc completed to a closed convex contour (cam frame, shape (n, 2) [m]), so a
    ``curve_roll``/``curve_drum`` can carry it.  The arc's support function p(nu) (the distance of
    the band line from the pivot over the direction nu of its outward normal, exact from the trace)
    is continued over the normal directions the band never touches by ``belt_contour.close_arc``,
    the one arc closure (C4 joins, else C2 joins with a ``ClosureWarning``; else
    ``contour_not_closed``) that ``arc: true`` tables use too.
    The band only ever touches the arc, so the fill's shape does not enter the motion."""
    tr = curve.trace
    f = np.einsum("nij,nj->ni", _rot(-tr.cam), tr.foot - tr.pivot)
    nu = np.unwrap(np.arctan2(f[:, 1], f[:, 0]))
    p, c = np.hypot(*f.T), curve.contour
    if nu[-1] < nu[0]:
        nu, p, c = nu[::-1], p[::-1], c[::-1]
    gap = nu[0] + 2 * math.pi - nu[-1]
    m = max(8, int(math.ceil(gap / float(np.median(np.diff(nu))))))
    fill = close_arc(nu, p, m, "synthesised arc")
    cf = np.stack([fill.p * np.cos(fill.nu) - fill.dp * np.sin(fill.nu),
                   fill.p * np.sin(fill.nu) + fill.dp * np.cos(fill.nu)], -1)
    return np.concatenate([c, cf])


@dataclass
class Synthesis:
    """Result of :func:`synthesise_contour`: the ``trace``, the ``curve`` (:class:`BandCurve`), the
    ``assessment`` and, if written, the table ``(theta, r)`` and its ``path``."""

    trace: Trace
    curve: BandCurve
    assessment: Assessment
    theta: np.ndarray | None = None
    r: np.ndarray | None = None
    path: Path | None = None

    def report(self) -> str:
        """A short text: producible or not, the largest cam radius, every finding."""
        a = self.assessment
        lines = [f"band curve: {'producible' if a.producible else 'NOT producible'}; largest cam radius "
                 f"{a.max_radius:.6g} m; free band length {np.min(a.free_length):.6g} .. "
                 f"{np.max(a.free_length):.6g} m"]
        lines += [str(f) for f in a.findings]
        return "\n".join(lines)


def synthesise_contour(structure, transfer: Transfer, phi, path=None, *, torque=None, band=None,
                       max_radius=None) -> Synthesis:
    """Synthesise the band-curve contour of ``structure`` (:class:`DBSD`, :class:`DBBD`, :class:`DBDS`
    or :class:`DBDD`) for the
    transfer function ``transfer`` over the drive angles ``phi`` [rad] (a fine increasing grid),
    assess it (:func:`assess`; every warning is issued as a :class:`SynthesisWarning`) and, with ``path``,
    write the contour table (:func:`write_contour_table`).  A contour that cannot exist is not
    written: ``ModelError`` with code ``contour_not_producible``."""
    phi = np.asarray(phi, float)
    if phi.ndim != 1 or len(phi) < 5 or np.any(np.diff(phi) <= 0):
        raise ModelError("bad_value", "synthesis: phi must be an increasing grid of at least 5 angles",
                         "give e.g. numpy.linspace(phi_start, phi_end, 1001)")
    trace = structure.trace(phi, transfer)
    curve = band_curve(trace)
    a = assess(curve, transfer, torque=torque, band=band, max_radius=max_radius)
    for f in a.findings:
        if f.severity == "warning":
            warnings.warn(str(f), SynthesisWarning, stacklevel=2)
    syn = Synthesis(trace, curve, a)
    if path is not None:
        if not a.producible:
            f = next(f for f in a.findings if f.code == "contour_not_producible")
            raise ModelError(f.code, f"{path}: {f.message}", f.fix)
        syn.theta, syn.r = write_contour_table(path, curve.contour)
        syn.path = Path(path)
    return syn


# -- chapter 6: spring-band balancing ----------------------------------------------------------------

@dataclass
class Balance:
    """Result of :func:`spring_band_balance`: the spring travel ``x`` as a :class:`Transfer`
    (x(phi) [m], h = x' [m], h' [m/rad], h'' [m/rad^2]), the spring rate ``c`` [N/m], the travel
    ``x_start`` at the first angle [m] and the angle range ``phi0``, ``phi1`` [rad]."""

    x: Transfer
    c: float
    x_start: float
    phi0: float
    phi1: float


def spring_band_balance(torque, phi0: float, phi1: float, c: float, *, x_start: float | None = None,
                        h_max: float | None = None, n: int = 2001) -> Balance:
    """Spring travel x_S(phi) whose spring force c*x_S on the lever arm h = x_S' gives the torque
    T(phi) [N*m] over [phi0, phi1] [rad] (Ebert 6.3-6.5), by the closed-form quadrature of the
    separable equation T = c x x' (energy balance: c/2 (x^2 - x_start^2) = integral of T):

        x_S = sqrt(x_start^2 + 2/c * W(phi)),  W = int_phi0^phi T,   h = T/(c x_S).

    ``torque``: a :class:`Transfer` (T and its derivatives) or a callable T(phi) (then sampled on
    ``n`` points and interpolated by a quintic spline).  ``c`` [N/m]: spring rate.  ``x_start``
    [m]: spring extension at phi0; or ``h_max`` [m]: the smallest ``x_start`` whose lever arm stays
    within h_max (Ebert 7.2.1: h < 80 mm).  W is integrated exactly for the spline (its error is
    the interpolation error of T, O(dphi^6))."""
    if not c > 0:
        raise ModelError("bad_value", f"spring-band balancing: spring rate c = {c!r} N/m must be > 0",
                         "give the spring rate in N/m (0.938 N/mm = 938 N/m)")
    grid = np.linspace(phi0, phi1, n)
    if not isinstance(torque, Transfer):
        torque = Transfer.from_table(grid, np.asarray(torque(grid), float))
    T = torque(grid)
    spl = interpolate.make_interp_spline(grid, T, k=5)
    W = spl.antiderivative()
    W0 = float(W(phi0))

    def work(p):
        return np.asarray(W(np.asarray(p, float)), float) - W0

    Wg = work(grid)
    if x_start is None:
        if h_max is None or not h_max > 0:
            raise ModelError("bad_value", "spring-band balancing: give x_start or a positive h_max",
                             "x_start: spring extension at phi0 [m]; h_max: largest lever arm [m]")
        lo = math.sqrt(max(0.0, float(np.max(-2 * Wg / c)))) * (1 + 1e-12) + 1e-15

        def excess(x0):
            return float(np.max(np.abs(T) / (c * np.sqrt(x0 * x0 + 2 * Wg / c)))) - h_max

        hi = max(2 * lo, 1e-3)
        while excess(hi) > 0:
            hi *= 2
        x_start = lo if excess(lo) <= 0 else optimize.brentq(excess, lo, hi, xtol=1e-15, rtol=1e-14)
    if np.any(x_start ** 2 + 2 * Wg / c <= 0):
        raise ModelError("bad_value", "spring-band balancing: the spring would have to be compressed "
                         "(x_S^2 <= 0 somewhere)", "raise x_start or the spring rate")

    def xs(p):
        return np.sqrt(x_start ** 2 + 2 * work(p) / c)

    def h(p):
        return torque(p) / (c * xs(p))

    def dh(p):
        return (torque(p, 1) - c * h(p) ** 2) / (c * xs(p))

    def ddh(p):
        return (torque(p, 2) - 3 * c * h(p) * dh(p)) / (c * xs(p))

    return Balance(Transfer(xs, h, dh, ddh), float(c), float(x_start), float(phi0), float(phi1))


@dataclass
class SpringBandAnalysis:
    """Result of :func:`spring_band_analysis` over the cam angles ``phi`` [rad]: the lever arm
    ``h`` [m], the spring travel ``x`` [m], the torque ``torque`` = c x h [N*m] the spring exerts
    (counted against the winding direction), and the contact point's polar angle ``theta`` [rad]."""

    phi: np.ndarray
    h: np.ndarray
    x: np.ndarray
    torque: np.ndarray
    theta: np.ndarray


def spring_band_analysis(table, phi, p1, p2, c: float, x_start: float, *, K: int = 1) -> SpringBandAnalysis:
    """Torque of a spring band (DB~SD) through a contour table, evaluated from the contour geometry
    alone: for each cam angle phi [rad] the band line is the tangent from the spring pivot ``p2``
    to the contour turned by K*phi about ``p1`` [m], the lever arm h its distance from ``p1``
    (sign: + when the band is wound on by the positive cam angle), the spring travel x the change
    of the band length from P2 round the contour (free span + wrapped arc) added to ``x_start``
    [m] at the first angle, and the torque c*x*h [N*m].  ``table``: a path or ``(theta, r)``."""
    theta_t, r_t = read_contour_table(table) if isinstance(table, (str, Path)) else map(np.asarray, table)
    spl = interpolate.CubicSpline(theta_t, r_t)
    dspl = spl.derivative()
    p1, p2 = np.asarray(p1, float), np.asarray(p2, float)
    phi = np.asarray(phi, float)

    def point(t):
        t = np.asarray(t, float)
        return (spl(t) * np.array([np.cos(t), np.sin(t)])).T

    def tangent(t):
        t = np.asarray(t, float)
        return (dspl(t) * np.array([np.cos(t), np.sin(t)]) + spl(t) * np.array([-np.sin(t), np.cos(t)])).T

    # arc length along the contour: 10-point Gauss-Legendre on every spline interval (the spline is
    # a polynomial there, its arc-length integrand smooth), cumulated at the knots
    xg, wg = np.polynomial.legendre.leggauss(10)

    def _gauss(a, b):
        t = 0.5 * (a + b)[..., None] + 0.5 * (b - a)[..., None] * xg
        return 0.5 * (b - a) * (np.hypot(spl(t), dspl(t)) @ wg)

    S_knots = np.r_[0.0, np.cumsum(_gauss(theta_t[:-1], theta_t[1:]))]

    def S(t):
        k = min(max(int(np.searchsorted(theta_t, t)) - 1, 0), len(theta_t) - 2)
        return S_knots[k] + float(_gauss(np.array(theta_t[k]), np.array(t)))

    def arc(t0, t1):
        return S(t1) - S(t0)

    grid = np.linspace(theta_t[0], theta_t[-1], 4 * len(theta_t))
    pts, tans = point(grid), tangent(grid)
    hs, free, thetas, sgn = [], [], [], []
    for a in K * phi:
        c_, s_ = math.cos(a), math.sin(a)
        q = np.array([[c_, s_], [-s_, c_]]) @ (p2 - p1)     # P2 in the cam frame

        def f(t):
            return float(_cross(point(t) - q, tangent(t)))

        vals = _cross(pts - q, tans)
        roots = []
        for k in _sign_changes(np.sign(vals)):
            t = optimize.brentq(f, grid[k], grid[k + 1], xtol=1e-16, rtol=1e-15)
            e = point(t) - q
            lever = K * float(_cross(point(t), e / np.linalg.norm(e)))
            roots.append((t, lever, float(np.linalg.norm(e))))
        if not roots:
            raise ModelError("no_tangent", f"spring-band analysis: no tangent from P2 to the contour at "
                             f"phi = {a * K:.6g} rad", "the contour table does not cover this cam angle")
        # the band winds on under a positive cam angle: lever > 0 (a tension band cannot push)
        t, lever, dist = max(roots, key=lambda z: z[1])
        thetas.append(t)
        hs.append(lever)
        free.append(dist)
        sgn.append(math.copysign(1.0, float(tangent(t) @ (point(t) - q))))
    thetas, hs, free = np.array(thetas), np.array(hs), np.array(free)
    # the band goes on round the contour in its own direction: the wrapped arc grows toward
    # decreasing theta when the contour's theta-tangent points along the band (and vice versa)
    wrapped = np.array([-s * arc(thetas[0], t) for s, t in zip(sgn, thetas)])
    x = x_start + (free - free[0]) + wrapped
    return SpringBandAnalysis(phi, hs, x, c * x * hs, thetas)


# -- the worked example: a wall-cabinet door (Ebert 6.4 / 7.2.1) ---------------------------------

@dataclass(frozen=True)
class CabinetDoor:
    """The cabinet door of Ebert 7.2.1 as a closed-form example.  The door blade is the coupler of
    a parallelogram four-bar (rockers of length ``L`` [m]), so it translates and its centre of mass
    (``m`` [kg], the thesis's 2 kg test mass on one hinge) rises by L*sin(psi) with the rocker angle
    psi [rad].  The cam sits on the door-side rocker; the drive angle phi = ``psi_open`` - psi runs
    from the open door (phi = 0) to the closed one (phi = ``travel``), so the spring is stretched as
    the door falls.  Ebert's spring rate 0.938 N/mm, his pivots A0 = (0, 0) and B0 = (-296, 0) mm
    and the right-hand mounting (K = -1) are kept; ``L``, the angles and ``x_start`` (spring
    extension at the open door [m]) are ours (the thesis's torque curve is in a missing figure).
    The balancing torque (the torque that holds the door) is T(phi) = m g L cos(psi_open - phi)."""

    m: float = 2.0
    L: float = 0.15
    psi_open: float = math.radians(50.0)
    psi_closed: float = math.radians(-70.0)
    c: float = 938.0
    p1: tuple = (0.0, 0.0)
    p2: tuple = (-0.296, 0.0)
    K: int = -1
    x_start: float = 0.038
    g: float = 9.81

    @property
    def travel(self) -> float:
        """Drive angle from the open to the closed door [rad]."""
        return self.psi_open - self.psi_closed

    def torque(self) -> Transfer:
        """T(phi) = m g L cos(psi_open - phi) [N*m] and its derivatives."""
        a, po = self.m * self.g * self.L, self.psi_open
        return Transfer(lambda p: a * np.cos(po - p), lambda p: a * np.sin(po - p),
                        lambda p: -a * np.cos(po - p), lambda p: -a * np.sin(po - p))

    def balance(self, margin: float = 0.05) -> Balance:
        """The spring travel (:func:`spring_band_balance`) over the travel widened by ``margin``
        [rad] at both ends (so the contour covers the whole motion); the spring extension at the
        open door (phi = 0) is ``x_start``."""
        a, po = self.m * self.g * self.L, self.psi_open
        x0 = math.sqrt(self.x_start ** 2 - 2 * a * (math.sin(po + margin) - math.sin(po)) / self.c)
        return spring_band_balance(self.torque(), -margin, self.travel + margin, self.c, x_start=x0)

    def structure(self) -> DBSD:
        """The DB~SD structure with the door's pivots and mounting side."""
        return DBSD(self.p1, self.p2, K=self.K)
