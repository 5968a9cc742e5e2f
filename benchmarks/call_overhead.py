"""Cost of calling the model through a function address (how the numba backend's compiled loops call
the generated ``cfunc``s) against a direct call numba can inline (docs/performance.md, "Issue 11: a
new process").

The model is the drive train's right-hand side written once as Python (3 states, the motor torque
``10 (1 - exp(-t/0.05))``), compiled twice: as a ``cfunc`` with the backend's C signature, called
through :func:`multipole.backends.numba_kernels.call_model`, and as an ``njit`` function called
directly.  Each variant evaluates it N times in a compiled loop (the argument t changes, so
nothing is hoisted); rounds alternate, medians with [lowest-highest] of the CPU time per call.

    python benchmarks/call_overhead.py
"""
from __future__ import annotations

import math
import statistics
import time

import numpy as np
from numba import carray, cfunc, njit, types

from multipole.backends.numba_kernels import call_model

J_ROTOR, I_GEAR, C_SHAFT, D_SHAFT, J_LOAD, D_BEARING = 2.0e-3, 3.0, 2000.0, 0.5, 0.5, 0.8
N = 2_000_000


def body(t, x, out):
    """d/dt of (rotor speed, shaft twist, load speed) of the drive train."""
    torque = 10.0 * (1.0 - math.exp(-t / 0.05))
    spring = C_SHAFT * x[1] + D_SHAFT * (x[0] / I_GEAR - x[2])
    out[0] = (torque - spring / I_GEAR) / J_ROTOR
    out[1] = x[0] / I_GEAR - x[2]
    out[2] = (spring - D_BEARING * x[2]) / J_LOAD


direct_body = njit(body)


@cfunc(types.void(types.float64, types.voidptr, types.voidptr, types.voidptr))
def through_address(t, xp, outp, wp):
    x = carray(xp, (3,), np.float64)
    out = carray(outp, (3,), np.float64)
    direct_body(t, x, out)


@njit
def loop_address(address, n, x, out, w):
    acc = 0.0
    for i in range(n):
        call_model(address, i * 1e-7, x, out, w)
        acc += out[0]
    return acc


@njit
def loop_direct(n, x, out, w):
    acc = 0.0
    for i in range(n):
        direct_body(i * 1e-7, x, out)
        acc += out[0]
    return acc


def main() -> None:
    x, out, w = np.array([1.0, 1e-3, 0.3]), np.zeros(3), np.zeros(1)
    address = through_address.address
    runs = {"address": lambda: loop_address(address, N, x, out, w), "direct": lambda: loop_direct(N, x, out, w)}
    assert math.isclose(runs["address"](), runs["direct"](), rel_tol=1e-12)     # same work, compiled
    times: dict = {k: [] for k in runs}
    for _ in range(7):
        for name, fun in runs.items():
            start = time.process_time()
            fun()
            times[name].append((time.process_time() - start) / N * 1e9)
    for name, v in times.items():
        print(f"{name:8s} {statistics.median(v):6.2f} ns per call [{min(v):.2f}-{max(v):.2f}]")
    print(f"ratio address/direct {statistics.median(times['address']) / statistics.median(times['direct']):.2f}")


if __name__ == "__main__":
    main()
