"""Compiled integrator loops for the numba backend (:mod:`multipole.backends.numba_backend`).

Two one-step methods, each a transcription of the algorithm scipy uses (same coefficients, error
norms and step-size control), so that a run agrees with the ``numpy`` backend within the
tolerances and work counters are comparable:

* Dormand–Prince 5(4) with Shampine's 4th-order dense output (scipy ``RK45``), explicit;
* Radau IIA of order 5 (three-stage collocation, simplified Newton on the transformed system,
  Hairer & Wanner's error estimate and predictive step control; scipy ``Radau``), implicit,
  with the model's analytic Jacobian.

The driver :func:`integrate` also runs in compiled code: it samples the solution on the output
grid from the dense output, ends segments at the crossings of the switching functions of time
alone (found before the run), watches the others at :data:`PROBES` points of every step, finds the
earliest sign change by bisection on the dense output and restarts the method just past it (the
same event semantics as :func:`multipole.simulate.simulate`).  Everything the loop needs between steps lives in arrays
owned by the caller, so a run can be cut into chunks (for a progress bar) without changing a
single bit of the result.

The model functions are numba ``cfunc`` objects with the C signature
``void fun(double t, double *x, double *out, double *w)`` (``out`` is written, ``w`` is the
model's work array for Newton loops), passed in by address (``cfunc.address``, an integer) and
called through :func:`call_model`.  Called through function pointers, they leave these loops
independent of the model: the loops are compiled once and kept in numba's cache, and a new model
only compiles its own small functions.  (Passing the cfunc objects themselves as first-class
functions also works, but costs about 0.1 ms per call from Python and 0.1 us per model call.)
Time is in seconds; states and tolerances are in the model's units.
"""
from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

# -- layout of the scalar state arrays ------------------------------------------------------------
# fs (float64)
#: F_T_BOUND: where the current segment must end (t_end, or the next scheduled crossing of a
#: switching function of time alone); the methods never step past it
F_T, F_H, F_H_OLD, F_ERR_OLD, F_T_OLD, F_H_DENSE, F_T_END, F_RTOL, F_ATOL, F_MAX_STEP, F_T_BOUND = range(11)
N_FS = 11
#: the model's work array w: w[0] Newton iterations, w[1] Newton solves, w[2] Newton failures, then
#: one side (±1) per switching function (read by the model functions, set at every segment start),
#: then the Newton loops' guesses
W_HEAD = 3
# iw (int64)
(I_KOUT, I_NEV, I_STEPS, I_REJECTED, I_NFEV, I_NJEV, I_NLU, I_SEGMENTS, I_STATUS, I_FRESH,
 I_CURRENT_JAC, I_LU_OK, I_SOL_OK, I_FORCED, I_FORCED_SIGN, I_NEWTON_IT, I_SCHED) = range(17)
N_IW = 17
#: the watched switching functions are evaluated at this many equispaced points of every step (the
#: last is its end), as in :data:`multipole.simulate.PROBES`
PROBES = 5
# status codes
#: MONITOR_STOP: a stop monitor crossed from >= 0 to < 0 (the run ends at that event, the last one)
RUNNING, FINISHED, STEP_TOO_SMALL, TOO_MANY_EVENTS, NOT_FINITE, MONITOR_STOP = 0, 1, -1, -2, -3, -4
DENSE_COLS = 4          # columns of the dense-output coefficient matrix Q

SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 10.0
EPS = np.finfo(float).eps

# -- Dormand–Prince 5(4) ---------------------------------------------------------------------------
DP_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0])
DP_A = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0],
    [1 / 5, 0.0, 0.0, 0.0, 0.0],
    [3 / 40, 9 / 40, 0.0, 0.0, 0.0],
    [44 / 45, -56 / 15, 32 / 9, 0.0, 0.0],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0.0],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656]])
DP_B = np.array([35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84])
# difference of the 5th- and 4th-order weights (7 stages, the last is f at the new point)
DP_E = np.array([-71 / 57600, 0.0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])
# Shampine's dense output: y(t_old + theta*h) = y_old + h * K^T P [theta, theta^2, theta^3, theta^4]
DP_P = np.array([
    [1.0, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
    [0.0, 0.0, 0.0, 0.0],
    [0.0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
    [0.0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
    [0.0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
    [0.0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
    [0.0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423]])
DP_ORDER = 4            # order of the error estimator (step-size exponent -1/5)


# -- Radau IIA, order 5 ------------------------------------------------------------------------------
def _radau_tableau():
    """Nodes, the transformation of A^-1 to real Schur-like form, error and dense-output weights.

    ``A^-1 = T diag(mu_real, [[a, b], [-b, a]]) T^-1`` with ``mu_complex = a - i*b``: the
    collocation Newton system splits into one real and one complex n x n system.
    """
    s6 = np.sqrt(6.0)
    c = np.array([(4 - s6) / 10, (4 + s6) / 10, 1.0])
    # collocation matrix a_ij = int_0^{c_i} l_j(s) ds with the Lagrange polynomials l_j on c
    A = np.empty((3, 3))
    for j in range(3):
        others = [c[k] for k in range(3) if k != j]
        coef = np.poly(others) / np.prod([c[j] - o for o in others])
        integral = np.polyint(coef)
        A[:, j] = np.polyval(integral, c)
    lam, vec = np.linalg.eig(np.linalg.inv(A))
    real = int(np.argmin(np.abs(lam.imag)))
    cplx = int(np.argmax(lam.imag))
    mu_real = float(lam[real].real)
    mu_complex = complex(lam[cplx].real, -lam[cplx].imag)
    T = np.column_stack([vec[:, real].real, vec[:, cplx].real, vec[:, cplx].imag])
    TI = np.linalg.inv(T)
    # error estimate weights (Hairer & Wanner IV.8) and collocation polynomial in theta
    E = np.array([-13 - 7 * s6, -13 + 7 * s6, -1.0]) / 3
    P = np.array([[13 / 3 + 7 * s6 / 3, -23 / 3 - 22 * s6 / 3, 10 / 3 + 5 * s6],
                  [13 / 3 - 7 * s6 / 3, -23 / 3 + 22 * s6 / 3, 10 / 3 - 5 * s6],
                  [1 / 3, -8 / 3, 10 / 3]])
    return c, A, mu_real, mu_complex, T, TI, E, P


RA_C, RA_A, RA_MU_REAL, RA_MU_COMPLEX, RA_T, RA_TI, RA_E, RA_P = _radau_tableau()
RA_TI_REAL = RA_TI[0].copy()
RA_TI_COMPLEX = RA_TI[1] + 1j * RA_TI[2]
RA_ORDER = 3            # order of the error estimator used for the first step
NEWTON_MAXITER = 6


@intrinsic
def call_model(typingctx, address, t, x, out, w):
    """Call the model function ``void f(double t, double *x, double *out, double *w)`` at
    ``address`` with the data of the contiguous float64 arrays ``x``, ``out`` and ``w``."""
    sig = types.void(address, t, x, out, w)

    def codegen(context, builder, signature, args):
        byte_ptr = ir.IntType(8).as_pointer()
        ptrs = [builder.bitcast(context.make_array(ty)(context, builder, val).data, byte_ptr)
                for ty, val in zip(signature.args[2:], args[2:])]
        fnty = ir.FunctionType(ir.VoidType(), [ir.DoubleType(), byte_ptr, byte_ptr, byte_ptr])
        builder.call(builder.inttoptr(args[0], fnty.as_pointer()), [args[1]] + ptrs)
        return context.get_dummy_value()

    return sig, codegen


# -- small dense linear algebra (n is small; LAPACK call overhead would dominate) ------------------
@njit(cache=True)
def _pivot(A, k, n):
    """(row, |entry|) of the largest entry in magnitude of column k of ``A`` at or below row k."""
    p = k
    big = abs(A[k, k])
    for i in range(k + 1, n):
        if abs(A[i, k]) > big:
            big = abs(A[i, k])
            p = i
    return p, big


@njit(cache=True)
def _back_substitute(U, b):
    """Solve ``U z = b`` in place in ``b`` for the upper triangle of ``U`` (its diagonal included)."""
    n = b.size
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= U[i, j] * b[j]
        b[i] = s / U[i, i]


@njit(cache=True)
def lu_factor(A, piv):
    """LU with partial pivoting of ``A`` in place (real or complex); ``piv`` gets the row swaps."""
    n = A.shape[0]
    for k in range(n):
        p = _pivot(A, k, n)[0]
        piv[k] = p
        if p != k:
            for j in range(n):
                tmp = A[k, j]
                A[k, j] = A[p, j]
                A[p, j] = tmp
        d = A[k, k]
        if d == 0:
            continue          # singular: the solve produces inf/nan and the step is refused
        for i in range(k + 1, n):
            A[i, k] /= d
            a = A[i, k]
            if a != 0:
                for j in range(k + 1, n):
                    A[i, j] -= a * A[k, j]


@njit(cache=True)
def lu_solve(LU, piv, b):
    """Solve ``A z = b`` in place in ``b`` from :func:`lu_factor`'s output."""
    n = LU.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
    for i in range(n):
        s = b[i]
        for j in range(i):
            s -= LU[i, j] * b[j]
        b[i] = s
    _back_substitute(LU, b)


@njit(cache=True)
def gauss_solve(A, b):
    """Solve ``A z = b`` in place in ``b`` (``A`` overwritten) by Gaussian elimination with partial
    pivoting, the row swaps applied to ``b`` as they happen: no pivot array, so the generated code
    solves its small loops in views of the work array without allocating.  False (and ``b`` NaN) if
    a pivot is zero."""
    n = b.size
    for k in range(n):
        p, big = _pivot(A, k, n)
        if big == 0.0:
            for i in range(n):
                b[i] = np.nan
            return False
        if p != k:
            for j in range(k, n):
                tmp = A[k, j]
                A[k, j] = A[p, j]
                A[p, j] = tmp
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
        d = A[k, k]
        for i in range(k + 1, n):
            a = A[i, k]
            if a != 0.0:
                a /= d
                for j in range(k + 1, n):
                    A[i, j] -= a * A[k, j]
                b[i] -= a * b[k]
    _back_substitute(A, b)
    return True


@njit(cache=True)
def neg_solve(A, B):
    """``-A^-1 B`` for a square ``A`` and a matrix ``B`` (A is overwritten by its LU)."""
    n = A.shape[0]
    piv = np.empty(n, dtype=np.int64)
    lu_factor(A, piv)
    out = np.empty(B.shape)
    col = np.empty(n)
    for j in range(B.shape[1]):
        for i in range(n):
            col[i] = B[i, j]
        lu_solve(A, piv, col)
        for i in range(n):
            out[i, j] = -col[i]
    return out


@njit(cache=True)
def norm2(v):
    """Euclidean norm."""
    s = 0.0
    for i in range(v.size):
        s += v[i] * v[i]
    return np.sqrt(s)


@njit(cache=True)
def _rms_scaled(v, scale):
    s = 0.0
    for i in range(v.size):
        r = v[i] / scale[i]
        s += r * r
    return np.sqrt(s / v.size) if v.size else 0.0


@njit(cache=True)
def _min_step(t):
    return 10.0 * abs(np.nextafter(t, np.inf) - t)


@njit(cache=True)
def dense_eval(Q, y_old, t_old, h, tau, out):
    """``out = y_old + Q [theta, theta^2, ...]`` with ``theta = (tau - t_old)/h``."""
    theta = (tau - t_old) / h
    for i in range(out.size):
        acc = 0.0
        p = 1.0
        for j in range(Q.shape[1]):
            p *= theta
            acc += Q[i, j] * p
        out[i] = y_old[i] + acc


# -- first step ---------------------------------------------------------------------------------
@njit(cache=True)
def _initial_step(rhs, w, t0, y0, f0, order, rtol, atol, t_bound, max_step, iw):
    """Hairer's starting step (as scipy's ``select_initial_step``)."""
    n = y0.size
    interval = abs(t_bound - t0)
    if interval == 0.0:
        return 0.0
    scale = np.empty(n)
    for i in range(n):
        scale[i] = atol + abs(y0[i]) * rtol
    d0 = _rms_scaled(y0, scale)
    d1 = _rms_scaled(f0, scale)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h0 = min(h0, interval)
    y1 = np.empty(n)
    for i in range(n):
        y1[i] = y0[i] + h0 * f0[i]
    f1 = np.empty(n)
    call_model(rhs, t0 + h0, y1, f1, w)
    iw[I_NFEV] += 1
    for i in range(n):
        f1[i] -= f0[i]
    d2 = _rms_scaled(f1, scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1))
    return min(100 * h0, h1, interval, max_step)


# -- Dormand–Prince step ---------------------------------------------------------------------------
@njit(cache=True)
def dp_step(rhs, w, fs, iw, x, f, Q, y_old, ws):
    """One accepted DP5(4) step from (fs[F_T], x); False if the step size underflowed."""
    K, x_new, tmp, scale = ws[0:7], ws[7], ws[8], ws[9]
    n = x.size
    t = fs[F_T]
    rtol, atol, t_bound = fs[F_RTOL], fs[F_ATOL], fs[F_T_BOUND]
    min_step = _min_step(t)
    h_abs = min(fs[F_H], fs[F_MAX_STEP])
    if h_abs < min_step:
        h_abs = min_step
    rejected = False
    while True:
        if h_abs < min_step:
            return False
        t_new = min(t + h_abs, t_bound)
        h = t_new - t
        h_abs = abs(h)
        for i in range(n):
            K[0, i] = f[i]
        for s in range(1, 6):
            for i in range(n):
                acc = 0.0
                for j in range(s):
                    acc += DP_A[s, j] * K[j, i]
                tmp[i] = x[i] + h * acc
            call_model(rhs, t + DP_C[s] * h, tmp, K[s], w)
        for i in range(n):
            acc = 0.0
            for j in range(6):
                acc += DP_B[j] * K[j, i]
            x_new[i] = x[i] + h * acc
        call_model(rhs, t_new, x_new, K[6], w)
        iw[I_NFEV] += 6
        for i in range(n):
            acc = 0.0
            for j in range(7):
                acc += DP_E[j] * K[j, i]
            tmp[i] = acc * h
            scale[i] = atol + max(abs(x[i]), abs(x_new[i])) * rtol
        err = _rms_scaled(tmp, scale)
        if err < 1.0:
            factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err ** (-1.0 / (DP_ORDER + 1)))
            if rejected:
                factor = min(1.0, factor)
            fs[F_H] = h_abs * factor
            break
        h_abs *= max(MIN_FACTOR, SAFETY * err ** (-1.0 / (DP_ORDER + 1)))
        rejected = True
        iw[I_REJECTED] += 1
    for i in range(n):
        y_old[i] = x[i]
        for c in range(DENSE_COLS):
            acc = 0.0
            for j in range(7):
                acc += K[j, i] * DP_P[j, c]
            Q[i, c] = h * acc
    fs[F_T_OLD] = t
    fs[F_H_DENSE] = h
    fs[F_T] = t_new
    for i in range(n):
        x[i] = x_new[i]
        f[i] = K[6, i]
    return True


# -- Radau IIA step ---------------------------------------------------------------------------------
@njit(cache=True)
def _refactor(J, h, LUr, pr, LUc, pc, iw):
    n = J.shape[0]
    mr = RA_MU_REAL / h
    mc = RA_MU_COMPLEX / h
    for i in range(n):
        for j in range(n):
            LUr[i, j] = -J[i, j]
            LUc[i, j] = -J[i, j]
        LUr[i, i] += mr
        LUc[i, i] += mc
    lu_factor(LUr, pr)
    lu_factor(LUc, pc)
    iw[I_NLU] += 2
    iw[I_LU_OK] = 1


@njit(cache=True)
def _collocation(rhs, w, t, y, h, Z, scale, tol, LUr, pr, LUc, pc, iw, F, W, tmp, br, bc):
    """Simplified Newton iteration for the stage increments ``Z`` (3 x n), started from ``Z``.

    Returns (converged, iterations, rate)."""
    n = y.size
    mr = RA_MU_REAL / h
    mc = RA_MU_COMPLEX / h
    for k in range(3):
        for i in range(n):
            W[k, i] = RA_TI[k, 0] * Z[0, i] + RA_TI[k, 1] * Z[1, i] + RA_TI[k, 2] * Z[2, i]
    dw_old = -1.0
    rate = -1.0
    it = 0
    while it < NEWTON_MAXITER:
        it += 1
        finite = True
        for k in range(3):
            for i in range(n):
                tmp[i] = y[i] + Z[k, i]
            call_model(rhs, t + RA_C[k] * h, tmp, F[k], w)
            for i in range(n):
                if not np.isfinite(F[k, i]):
                    finite = False
        iw[I_NFEV] += 3
        iw[I_NEWTON_IT] += 1
        if not finite:
            return False, it, rate
        for i in range(n):
            br[i] = (RA_TI_REAL[0] * F[0, i] + RA_TI_REAL[1] * F[1, i] + RA_TI_REAL[2] * F[2, i]
                     - mr * W[0, i])
            bc[i] = (RA_TI_COMPLEX[0] * F[0, i] + RA_TI_COMPLEX[1] * F[1, i] + RA_TI_COMPLEX[2] * F[2, i]
                     - mc * (W[1, i] + 1j * W[2, i]))
        lu_solve(LUr, pr, br)
        lu_solve(LUc, pc, bc)
        s = 0.0
        for i in range(n):
            a = br[i] / scale[i]
            b = bc[i].real / scale[i]
            c = bc[i].imag / scale[i]
            s += a * a + b * b + c * c
        dw = np.sqrt(s / (3 * n))
        if dw_old >= 0.0:
            rate = dw / dw_old
        if rate >= 0.0 and (rate >= 1.0 or rate ** (NEWTON_MAXITER - it + 1) / (1.0 - rate) * dw > tol):
            return False, it, rate
        for i in range(n):
            W[0, i] += br[i]
            W[1, i] += bc[i].real
            W[2, i] += bc[i].imag
        for k in range(3):
            for i in range(n):
                Z[k, i] = RA_T[k, 0] * W[0, i] + RA_T[k, 1] * W[1, i] + RA_T[k, 2] * W[2, i]
        if dw == 0.0 or (rate >= 0.0 and rate / (1.0 - rate) * dw < tol):
            return True, it, rate
        dw_old = dw
    return False, it, rate


@njit(cache=True)
def _predict_factor(h_abs, h_abs_old, err, err_old):
    """Gustafsson's predictive controller (NaN = no history)."""
    if np.isnan(err_old) or np.isnan(h_abs_old) or err == 0.0:
        multiplier = 1.0
    else:
        multiplier = h_abs / h_abs_old * (err_old / err) ** 0.25
    if err == 0.0:
        return np.inf
    return min(1.0, multiplier) * err ** -0.25


@njit(cache=True)
def radau_step(rhs, jac, w, fs, iw, x, f, J, LUr, pr, LUc, pc, Q, y_old, ws, wc):
    """One accepted Radau IIA(5) step from (fs[F_T], x); False if the step size underflowed."""
    Z, F, W, x_new, tmp = ws[0:3], ws[3:6], ws[6:9], ws[9], ws[10]
    scale, br, ff, Zprev = ws[11], ws[12], ws[13], ws[14:17]
    bc = wc
    n = x.size
    t = fs[F_T]
    rtol, atol, t_bound, max_step = fs[F_RTOL], fs[F_ATOL], fs[F_T_BOUND], fs[F_MAX_STEP]
    newton_tol = max(10 * EPS / rtol, min(0.03, rtol ** 0.5))
    min_step = _min_step(t)
    if fs[F_H] > max_step:
        h_abs, h_abs_old, err_old = max_step, np.nan, np.nan
    elif fs[F_H] < min_step:
        h_abs, h_abs_old, err_old = min_step, np.nan, np.nan
    else:
        h_abs, h_abs_old, err_old = fs[F_H], fs[F_H_OLD], fs[F_ERR_OLD]
    rejected = False
    while True:
        if h_abs < min_step:
            return False
        t_new = min(t + h_abs, t_bound)
        h = t_new - t
        h_abs = abs(h)
        # starting guess: extrapolate the previous step's collocation polynomial
        for k in range(3):
            if iw[I_SOL_OK]:
                dense_eval(Q, y_old, fs[F_T_OLD], fs[F_H_DENSE], t + h * RA_C[k], tmp)
                for i in range(n):
                    Z[k, i] = tmp[i] - x[i]
            else:
                for i in range(n):
                    Z[k, i] = 0.0
        for i in range(n):
            scale[i] = atol + abs(x[i]) * rtol
        for k in range(3):
            for i in range(n):
                Zprev[k, i] = Z[k, i]
        converged = False
        n_iter = 0
        while True:
            if not iw[I_LU_OK]:
                _refactor(J, h, LUr, pr, LUc, pc, iw)
            for k in range(3):
                for i in range(n):
                    Z[k, i] = Zprev[k, i]
            converged, n_iter, rate = _collocation(rhs, w, t, x, h, Z, scale, newton_tol, LUr, pr, LUc, pc,
                                                   iw, F, W, tmp, br, bc)
            if converged or iw[I_CURRENT_JAC]:
                break
            call_model(jac, t, x, J, w)
            iw[I_NJEV] += 1
            iw[I_CURRENT_JAC] = 1
            iw[I_LU_OK] = 0
        if not converged:
            h_abs *= 0.5
            iw[I_LU_OK] = 0
            iw[I_REJECTED] += 1
            continue
        for i in range(n):
            x_new[i] = x[i] + Z[2, i]
            br[i] = f[i] + (RA_E[0] * Z[0, i] + RA_E[1] * Z[1, i] + RA_E[2] * Z[2, i]) / h
            ff[i] = br[i] - f[i]               # Z^T E / h, kept for the second estimate
            scale[i] = atol + max(abs(x[i]), abs(x_new[i])) * rtol
        lu_solve(LUr, pr, br)
        err = _rms_scaled(br, scale)
        safety = 0.9 * (2 * NEWTON_MAXITER + 1) / (2 * NEWTON_MAXITER + n_iter)
        if rejected and err > 1.0:
            for i in range(n):
                tmp[i] = x[i] + br[i]
            call_model(rhs, t, tmp, br, w)
            iw[I_NFEV] += 1
            for i in range(n):
                br[i] += ff[i]
            lu_solve(LUr, pr, br)
            err = _rms_scaled(br, scale)
        if err > 1.0:
            factor = _predict_factor(h_abs, h_abs_old, err, err_old)
            h_abs *= max(MIN_FACTOR, safety * factor)
            iw[I_LU_OK] = 0
            iw[I_REJECTED] += 1
            rejected = True
            continue
        break
    recompute_jac = n_iter > 2 and rate > 1e-3
    factor = min(MAX_FACTOR, safety * _predict_factor(h_abs, h_abs_old, err, err_old))
    if not recompute_jac and factor < 1.2:
        factor = 1.0
    else:
        iw[I_LU_OK] = 0
    call_model(rhs, t_new, x_new, f, w)
    iw[I_NFEV] += 1
    if recompute_jac:
        call_model(jac, t_new, x_new, J, w)
        iw[I_NJEV] += 1
        iw[I_CURRENT_JAC] = 1
    else:
        iw[I_CURRENT_JAC] = 0
    fs[F_H_OLD] = h_abs
    fs[F_ERR_OLD] = err
    fs[F_H] = h_abs * factor
    for i in range(n):
        y_old[i] = x[i]
        for c in range(3):
            Q[i, c] = Z[0, i] * RA_P[0, c] + Z[1, i] * RA_P[1, c] + Z[2, i] * RA_P[2, c]
        Q[i, 3] = 0.0
        x[i] = x_new[i]
    fs[F_T_OLD] = t
    fs[F_H_DENSE] = h
    fs[F_T] = t_new
    iw[I_SOL_OK] = 1
    return True


# -- the driver ------------------------------------------------------------------------------------
@njit(cache=True)
def _sign(v):
    return 1.0 if v > 0 else (-1.0 if v < 0 else 0.0)


@njit(cache=True)
def _locate(switches, w, k, Q, y_old, t_old, h, a, b, g_a, tmp, g):
    """Bisection for the sign change of switching function ``k`` in [a, b]; returns the end
    on the new side (so the restart sees the new law)."""
    for _ in range(200):
        if b - a <= 1e-14 * max(1.0, abs(b)) + 4 * EPS * abs(b):
            break
        m = 0.5 * (a + b)
        dense_eval(Q, y_old, t_old, h, m, tmp)
        call_model(switches, m, tmp, g, w)
        s = _sign(g[k])
        if s == g_a:
            a = m
        elif s == 0.0:
            b = m
            break
        else:
            b = m
    return b


@njit(cache=True)
def _record_event(ev_t, ev_k, iw, t, k):
    """Append the event (t [s], switching function k); False (status TOO_MANY_EVENTS) when full."""
    if iw[I_NEV] >= ev_t.size:
        iw[I_STATUS] = TOO_MANY_EVENTS
        return False
    ev_t[iw[I_NEV]] = t
    ev_k[iw[I_NEV]] = k
    iw[I_NEV] += 1
    return True


@njit(cache=True)
def integrate(rhs, jac, switches, implicit, fs, iw, x, f, grid, X, g_sign, ev_t, ev_k, Q,
              y_old, J, LUr, pr, LUc, pc, w, time_only, sched_t, sched_k, sched_side, t_side, stop, max_steps):
    """Advance the run by at most ``max_steps`` accepted steps (see the module docstring).

    ``implicit`` selects :func:`radau_step` (else :func:`dp_step`).  Switching functions with
    ``time_only[k]`` are not watched: their crossings ``sched_t`` (of function ``sched_k``, which
    then takes side ``sched_side``) end segments; ``t_side`` holds their current sides.  A crossing
    of function k from >= 0 to < 0 with ``stop[k]`` (a stop monitor) ends the run there
    (MONITOR_STOP, ``x`` and ``fs[F_T]`` at the event).
    ``iw[I_STATUS]`` is set to FINISHED when every grid point is filled, or to a negative code."""
    n = x.size
    n_sw = g_sign.size
    n_grid = grid.size
    t_end = fs[F_T_END]
    tol_t = 1e-12 * max(1.0, t_end)
    ws = np.empty((17, n))
    wc = np.empty(n, dtype=np.complex128)
    tmp = np.empty(n)
    probe = np.empty(n)
    g = np.empty(n_sw)
    g_new = np.empty(n_sw)
    n_watch = 0
    for k in range(n_sw):
        if not time_only[k]:
            n_watch += 1
    taken = 0
    while iw[I_KOUT] < n_grid and taken < max_steps:
        if iw[I_FRESH]:                       # start of a segment: t = 0 or just past an event
            t = fs[F_T]
            while iw[I_SCHED] < sched_t.size and sched_t[iw[I_SCHED]] <= t:    # a scheduled crossing
                k = sched_k[iw[I_SCHED]]
                t_side[k] = sched_side[iw[I_SCHED]]
                if not _record_event(ev_t, ev_k, iw, t, k):
                    return
                iw[I_SCHED] += 1
            fs[F_T_BOUND] = sched_t[iw[I_SCHED]] if iw[I_SCHED] < sched_t.size else t_end
            if n_sw:                          # the side every switch is held on in this segment
                call_model(switches, t, x, g, w)
                for k in range(n_sw):
                    g_sign[k] = _sign(g[k])
                if iw[I_FORCED] >= 0:
                    g_sign[iw[I_FORCED]] = iw[I_FORCED_SIGN]
                    iw[I_FORCED] = -1
                call_model(switches, t + 1e-9 * max(1.0, t_end), x, g, w)
                for k in range(n_sw):
                    if time_only[k]:
                        g_sign[k] = t_side[k]
                    elif g_sign[k] == 0.0:    # on the switch: the side it takes just after t
                        g_sign[k] = _sign(g[k]) if g[k] != 0.0 else 1.0
                    w[W_HEAD + k] = g_sign[k]
            call_model(rhs, t, x, f, w)
            iw[I_NFEV] += 1
            order = RA_ORDER if implicit else DP_ORDER
            fs[F_H] = _initial_step(rhs, w, t, x, f, order, fs[F_RTOL], fs[F_ATOL], fs[F_T_BOUND], fs[F_MAX_STEP],
                                    iw)
            fs[F_H_OLD] = np.nan
            fs[F_ERR_OLD] = np.nan
            if implicit:
                call_model(jac, t, x, J, w)
                iw[I_NJEV] += 1
                iw[I_CURRENT_JAC] = 1
                iw[I_LU_OK] = 0
                iw[I_SOL_OK] = 0
            iw[I_SEGMENTS] += 1
            iw[I_FRESH] = 0
        if implicit:
            ok = radau_step(rhs, jac, w, fs, iw, x, f, J, LUr, pr, LUc, pc, Q, y_old, ws, wc)
        else:
            ok = dp_step(rhs, w, fs, iw, x, f, Q, y_old, ws)
        if not ok:
            iw[I_STATUS] = STEP_TOO_SMALL
            return
        for i in range(n):
            if not np.isfinite(x[i]):
                iw[I_STATUS] = NOT_FINITE
                return
        iw[I_STEPS] += 1
        taken += 1
        t_old, h, t_new = fs[F_T_OLD], fs[F_H_DENSE], fs[F_T]
        t_stop = t_new
        event = -1
        if n_watch:          # the earliest crossing: the first probe interval where a switch left its side
            a = t_old
            for j in range(1, PROBES + 1):
                if j == PROBES:
                    b = t_new
                    for i in range(n):
                        probe[i] = x[i]
                else:
                    b = t_old + h * j / PROBES
                    dense_eval(Q, y_old, t_old, h, b, probe)
                call_model(switches, b, probe, g_new, w)
                for k in range(n_sw):
                    s_new = _sign(g_new[k])
                    if not time_only[k] and s_new != g_sign[k] and s_new != 0.0:
                        te = _locate(switches, w, k, Q, y_old, t_old, h, a, b, g_sign[k], tmp, g)
                        if event < 0 or te < t_stop:
                            event, t_stop = k, te
                if event >= 0:
                    break
                a = b
        while iw[I_KOUT] < n_grid and grid[iw[I_KOUT]] <= t_stop + tol_t:
            k_out = iw[I_KOUT]
            if grid[k_out] >= t_new:
                for i in range(n):
                    X[k_out, i] = x[i]
            else:
                dense_eval(Q, y_old, t_old, h, grid[k_out], X[k_out])
            iw[I_KOUT] += 1
        if event >= 0:
            dense_eval(Q, y_old, t_old, h, t_stop, x)
            fs[F_T] = t_stop
            if not _record_event(ev_t, ev_k, iw, t_stop, event):
                return
            stopping = stop[event] and g_sign[event] > 0.0
            # switches that crossed at the same instant (a monitor on a law's own switching function)
            # are events of their own: the restart holds them on the new side they have at t_stop
            call_model(switches, t_stop, x, g, w)
            for k in range(n_sw):
                s_now = _sign(g[k])
                if k != event and not time_only[k] and s_now != 0.0 and s_now != g_sign[k]:
                    if not _record_event(ev_t, ev_k, iw, t_stop, k):
                        return
                    stopping = stopping or (stop[k] and g_sign[k] > 0.0)
            if stopping:
                iw[I_STATUS] = MONITOR_STOP
                return
            iw[I_FORCED] = event
            iw[I_FORCED_SIGN] = -int(g_sign[event])
            iw[I_FRESH] = 1
        elif t_new >= fs[F_T_BOUND] and fs[F_T_BOUND] < t_end:    # a scheduled crossing: new segment
            iw[I_FRESH] = 1
        elif t_new >= t_end:
            while iw[I_KOUT] < n_grid:
                for i in range(n):
                    X[iw[I_KOUT], i] = x[i]
                iw[I_KOUT] += 1
    if iw[I_KOUT] >= n_grid:
        iw[I_STATUS] = FINISHED


@njit(cache=True)
def sample(outputs, w, grid, X, Y):
    """``Y[k] = outputs(grid[k], X[k])``."""
    for k in range(grid.size):
        call_model(outputs, grid[k], X[k], Y[k], w)

