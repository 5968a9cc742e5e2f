"""Error of the regularised friction law against the exact piecewise stick-slip solution.

    python benchmarks/stick_slip_regularisation.py

For (v_reg, v_s) from coarse to fine, with v_s = 100 v_reg and v_s = 1000 v_reg, the scene
stick_slip (multipole_models) is run with Radau at rtol 1e-8 and compared with
``stick_slip_exact``: the largest position error relative to the largest deflection, the error of
the first breakaway time (both detected as the slip speed passing 1 mm/s), the work (steps, nfev,
njev), and the position error again at rtol 1e-11 (if it does not change, the error is the
regularised model's, not the solver's).  Writes stick_slip.csv.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from multipole_models import stick_slip, stick_slip_exact
from multipole.bench import write_rows
from multipole import pipeline
from multipole.netlist import loads

ROOT = Path(__file__).resolve().parents[1]
SETTINGS = [(1e-4, 1e-2), (1e-5, 1e-3), (1e-6, 1e-4), (1e-7, 1e-5), (1e-6, 1e-3), (1e-7, 1e-4), (1e-8, 1e-5)]
FIELDS = ["v_reg", "v_s", "err_x", "break_error_s", "steps", "nfev", "njev", "wall_s", "stiffness_1_per_s",
          "err_x_tight"]


def run(out=ROOT / "docs" / "bench", verbose=True):
    rows = []
    for v_reg, v_s in SETTINGS:
        sc = loads(stick_slip(v_reg=v_reg, v_s=v_s), "stick_slip.yaml")
        p = {k: float(v) for k, v in sc.network.params.items()}
        res = pipeline.run(sc, solver="Radau", dt_out=1e-4, progress=False)
        xe, ve, info = stick_slip_exact(res.t, **p)
        x, v = res["spring.deflection"], res["body.v"]

        def breakaway(speed):
            return res.t[np.argmax(np.abs(speed - p["v_belt"]) > 1e-3)]
        tight = pipeline.run(sc, solver="Radau", dt_out=1e-4, rtol=1e-11, atol=1e-13, progress=False)
        scale = np.max(np.abs(xe))
        rows.append({"v_reg": v_reg, "v_s": v_s, "err_x": np.max(np.abs(x - xe)) / scale,
                     "break_error_s": breakaway(v) - breakaway(ve), "steps": res.stats["steps"],
                     "nfev": res.stats["nfev"], "njev": res.stats["njev"], "wall_s": res.stats["wall_time"],
                     "stiffness_1_per_s": p["F_s"] / (p["m"] * v_reg),
                     "err_x_tight": np.max(np.abs(tight["spring.deflection"] - xe)) / scale})
        if verbose:
            r = rows[-1]
            print(f"v_reg {v_reg:.0e} v_s {v_s:.0e}: error {r['err_x']:.2e}, breakaway {r['break_error_s']:+.2e} s, "
                  f"steps {r['steps']}, nfev {r['nfev']}", flush=True)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_rows(rows, FIELDS, out / "stick_slip.csv")
    return rows


if __name__ == "__main__":
    run()
