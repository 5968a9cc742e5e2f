"""The integrators a scene may name (:data:`SOLVERS`: scipy's and the extra ones defined here).

Extra integrators with scipy's ``OdeSolver`` interface:

:class:`GaussLegendre` — implicit Runge–Kutta collocation at the ``s`` Gauss–Legendre points
(order ``2s``; ``s = 1`` is the implicit midpoint rule).  Gauss methods are symplectic and conserve
every *quadratic* invariant of the ODE exactly, for any sequence of step sizes (Hairer, Lubich &
Wanner, *Geometric Numerical Integration*, Thm. IV.2.2): the energy of a linear conservative
system (momenta and spring deflections as states) stays at its initial value up to round-off and
the Newton tolerance, where explicit and BDF/Radau methods drift.  They are A-stable but not
L-stable: for stiff *damped* problems use Radau or BDF.

Step-size control is by step doubling (one step of ``h`` against two of ``h/2``, error estimate
``(y_{h/2} - y_h)/(2^{2s} - 1)``, the two half steps are kept), so the estimate has the method's own
order and tolerances mean what they say.  Dense output is the quintic Hermite interpolant through
the start, middle and end of the step and the derivatives there (error O(h⁶) per step).

Work counters as in scipy: ``nfev``, ``njev``, ``nlu``; plus ``n_rejected`` (rejected steps) and
``newton_iterations``.
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, DenseOutput, OdeSolver, Radau
from scipy.linalg import lu_factor, lu_solve

__all__ = ["GaussLegendre", "GL4", "gauss_legendre_tableau"]

_EPS = np.finfo(float).eps


def gauss_legendre_tableau(s: int):
    """Butcher tableau ``(A, b, c)`` of the ``s``-stage Gauss–Legendre collocation method.

    ``c`` are the roots of the shifted Legendre polynomial on [0, 1]; ``A[i, j] = ∫_0^{c_i} ℓ_j``
    and ``b[j] = ∫_0^1 ℓ_j`` with ``ℓ_j`` the Lagrange basis on ``c``.
    """
    c = np.sort((legendre.legroots([0] * s + [1]) + 1) / 2)
    A = np.empty((s, s))
    b = np.empty(s)
    for j in range(s):
        others = np.delete(c, j)
        lj = np.poly1d(np.poly(others)) / np.prod(c[j] - others) if s > 1 else np.poly1d([1.0])
        Lj = lj.integ()
        b[j] = Lj(1.0) - Lj(0.0)
        A[:, j] = Lj(c) - Lj(0.0)
    return A, b, c


def _hermite5_inverse():
    """Inverse of the map from polynomial coefficients (degree 5) to (p, p') at θ = 0, 1/2, 1."""
    M = np.zeros((6, 6))
    for row, th in enumerate((0.0, 0.5, 1.0)):
        M[row] = [th**k for k in range(6)]
        M[3 + row] = [k * th ** (k - 1) if k else 0.0 for k in range(6)]
    return np.linalg.inv(M)


_H5 = _hermite5_inverse()


class GaussLegendre(OdeSolver):
    """Gauss–Legendre implicit Runge–Kutta method with ``stages`` stages (order ``2*stages``).

    Parameters as :class:`scipy.integrate.Radau`: ``fun``, ``t0``, ``y0``, ``t_bound``, ``rtol``,
    ``atol``, ``jac`` (callable or None for finite differences), ``max_step``, ``first_step``;
    and ``stages`` (default 2).  The nonlinear stage equations are solved by a simplified Newton
    iteration to round-off level, so that quadratic invariants are conserved.
    """

    MAX_NEWTON = 12

    def __init__(self, fun, t0, y0, t_bound, max_step=np.inf, rtol=1e-6, atol=1e-9, jac=None,
                 first_step=None, vectorized=False, stages=2, **extraneous):
        super().__init__(fun, t0, y0, t_bound, vectorized)
        self.s = int(stages)
        self.A, self.b, self.c = gauss_legendre_tableau(self.s)
        self.d = np.linalg.solve(self.A.T, self.b)       # y1 = y0 + d·Z  (d = A^-T b)
        self.order = 2 * self.s
        self.max_step = float(max_step)
        self.rtol = max(float(rtol), 100 * _EPS)
        self.atol = np.asarray(atol, dtype=float)
        self._jac = jac
        self.n_rejected = 0
        self.newton_iterations = 0
        self.f = self.fun(self.t, self.y)
        self.J = self._jacobian(self.t, self.y, self.f)
        self._lu = {}                           # step size -> LU of I - h A⊗J
        self._interp = None                     # (t_old, h, coefficients) of the last step
        if first_step is None:
            scale = self.atol + self.rtol * np.abs(self.y)
            d0, d1 = np.linalg.norm(self.y / scale), np.linalg.norm(self.f / scale)
            h = 0.01 * d0 / d1 if d0 > 1e-5 and d1 > 1e-5 else 1e-6
            h = min(h, 0.1 * abs(t_bound - t0)) if t_bound != t0 else h
        else:
            h = float(first_step)
        self.h_abs = min(h, self.max_step)

    # -- pieces ----------------------------------------------------------------------------------
    def _jacobian(self, t, y, f):
        self.njev += 1
        if self._jac is None:
            n = len(y)
            J = np.empty((n, n))
            for j in range(n):
                dy = np.sqrt(_EPS) * max(1.0, abs(y[j]))
                yp = y.copy()
                yp[j] += dy
                J[:, j] = (self.fun(t, yp) - f) / dy
            return J
        J = self._jac(t, y) if callable(self._jac) else self._jac
        return np.asarray(J.toarray() if hasattr(J, "toarray") else J, dtype=float)

    def _factor(self, h):
        """Solver of ``(I - h A⊗J) z = r``: an explicit inverse for small systems, else an LU."""
        if h not in self._lu:
            n, s = self.n, self.s
            M = np.eye(n * s) - h * np.kron(self.A, self.J)
            self.nlu += 1
            if n * s <= 64:
                inv = np.linalg.inv(M)
                self._lu[h] = inv.dot
            else:
                lu = lu_factor(M, check_finite=False)
                self._lu[h] = lambda r, lu=lu: lu_solve(lu, r, check_finite=False)
        return self._lu[h]

    def _solve_stages(self, t, y, h, Z0):
        """Stage increments ``Z`` (s×n) of one step of size ``h`` from ``(t, y)``; None on failure."""
        solve = self._factor(h)
        Z = Z0.copy()
        tc = t + self.c * h
        prev = None
        scale = self.atol + self.rtol * np.abs(y)
        for it in range(1, self.MAX_NEWTON + 1):
            F = np.array([self.fun(tc[i], y + Z[i]) for i in range(self.s)])
            if not np.all(np.isfinite(F)):
                return None
            G = Z - h * (self.A @ F)
            dZ = solve(-G.ravel()).reshape(self.s, self.n)
            Z += dZ
            self.newton_iterations += 1
            size = np.max(np.abs(dZ))
            roundoff = 16 * _EPS * (np.max(np.abs(y)) + np.max(np.abs(Z)) + 1e-300)
            if size <= roundoff:
                return Z
            if prev is not None:
                rate = size / prev
                if rate < 1.0 and size * rate / (1 - rate) <= roundoff:   # next increment below round-off
                    return Z
                if rate >= 1.0:
                    # stalled at round-off level: accept; otherwise diverging
                    return Z if np.max(np.abs(dZ) / scale) <= 1e-6 else None
            prev = size
        return Z if np.max(np.abs(dZ) / scale) <= 1e-6 else None

    def _gauss_step(self, t, y, h, guess):
        Z = self._solve_stages(t, y, h, guess(t, y, h))
        if Z is None:
            return None
        return y + self.d @ Z

    def _guess(self, t, y, h):
        """Starting stage increments from the previous step's interpolant (else from f)."""
        if self._interp is not None:
            t_old, h_old, coef = self._interp
            th = (t + self.c * h - t_old) / h_old
            return np.vander(th, 6, increasing=True) @ coef - y
        f = self.fun(t, y) if self.t != t else self.f
        return np.outer(self.c * h, f)

    # -- the step ----------------------------------------------------------------------------------
    def _step_impl(self):
        t, y = self.t, self.y
        h = min(self.h_abs, self.max_step)
        refreshed = False
        iterations = self.newton_iterations
        while True:
            if abs(self.t_bound - t) <= h * (1 + 1e-12):
                h = abs(self.t_bound - t)
            if h < 10 * np.abs(np.nextafter(t, self.direction * np.inf) - t):
                return False, "step size too small"
            d = self.direction
            y_big = self._gauss_step(t, y, d * h, self._guess)
            y_mid = self._gauss_step(t, y, d * h / 2, self._guess) if y_big is not None else None
            y_new = self._gauss_step(t + d * h / 2, y_mid, d * h / 2, self._guess) if y_mid is not None else None
            if y_new is None:
                if not refreshed:                      # Newton failed: fresh Jacobian first
                    self.J = self._jacobian(t, y, self.f)
                    self._lu.clear()
                    refreshed = True
                    continue
                self.n_rejected += 1
                h *= 0.5
                continue
            scale = self.atol + self.rtol * np.maximum(np.abs(y), np.abs(y_new))
            err = np.sqrt(np.mean(((y_new - y_big) / (2**self.order - 1) / scale) ** 2))
            factor = 0.9 * (err if err > 0 else 1e-10) ** (-1.0 / (self.order + 1))
            if err > 1.0:
                self.n_rejected += 1
                h *= max(0.2, factor)
                continue
            break
        f_mid = self.fun(t + d * h / 2, y_mid)
        f_new = self.fun(t + d * h, y_new)
        coef = _H5 @ np.array([y, y_mid, y_new, d * h * self.f, d * h * f_mid, d * h * f_new])
        self._interp = (t, d * h, coef)
        self.t_old_step = t
        self.t = t + d * h
        self.y, self.f = y_new, f_new
        if self.newton_iterations - iterations > 3 * 4:   # slow Newton: Jacobian at the new point
            self.J = self._jacobian(self.t, self.y, self.f)
            self._lu.clear()
        factor = min(4.0, factor)
        if not 1.0 <= factor <= 1.5:                  # keep h (and its LU) for small changes
            self.h_abs = min(h * factor, self.max_step)
            self._lu = {k: v for k, v in self._lu.items() if abs(k) in (self.h_abs, self.h_abs / 2)}
        else:
            self.h_abs = h
        return True, None

    def _dense_output_impl(self):
        t_old, h, coef = self._interp
        return _HermiteDense(t_old, t_old + h, coef)


class _HermiteDense(DenseOutput):
    """Quintic Hermite interpolant of one step (coefficients in θ = (t - t_old)/h)."""

    def __init__(self, t_old, t, coef):
        super().__init__(t_old, t)
        self.h = t - t_old
        self.coef = coef

    def _call_impl(self, t):
        th = (np.asarray(t, dtype=float) - self.t_old) / self.h
        y = np.zeros((self.coef.shape[1],) + th.shape)
        for k in range(5, -1, -1):                    # Horner
            y = y * th + (self.coef[k][:, None] if th.ndim else self.coef[k])
        return y


class GL4(GaussLegendre):
    """Two-stage Gauss–Legendre method (order 4): the registered solver ``GL4``."""

    def __init__(self, fun, t0, y0, t_bound, **kw):
        kw.pop("stages", None)
        super().__init__(fun, t0, y0, t_bound, stages=2, **kw)


#: integrators by the name ``simulate: {solver: ...}`` and ``--solver`` use (besides ``auto``); the
#: netlist loader validates names against it and :mod:`multipole.simulate` runs them
SOLVERS = {"RK45": RK45, "RK23": RK23, "DOP853": DOP853, "Radau": Radau, "BDF": BDF, "LSODA": LSODA, "GL4": GL4}
