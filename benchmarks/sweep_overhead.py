"""Benchmark of docs/performance.md, "Parameter studies": what a study costs beyond its solves.

A 1,000-run study of a small scene (a mass on a spring with a damper, 2 states, stiffness swept
over a log range) is run

* serially in this process: per-run cost against the median time of one warm solve of the same
  compiled model (``simulate`` alone, no study around it) -- the study's own overhead;
* on a local process pool of 2 workers: the speed-up over the serial study (start-up included);
* on a ``dask.distributed.LocalCluster`` of 2 worker processes (if installed): what Dask adds.

Run:  python benchmarks/sweep_overhead.py [--runs 1000]      (under a minute on 2 cores)
"""
from __future__ import annotations

import argparse
import tempfile
import textwrap
import time
from pathlib import Path

SCENE = textwrap.dedent("""\
    name: damped_oscillator
    parameters: {k: 100.0}
    elements:
      body:   {type: mass, m: 1.0}
      spring: {type: spring, c: k, x0: 0.01, domain: translational}
      damper: {type: damper, d: 0.5, domain: translational}
      wall:   {type: ground, domain: translational}
    connections:
      - [wall.p, spring.a, damper.a]
      - [spring.b, damper.b, body.a]
    outputs: [spring.deflection, body.v]
    simulate: {t_end: 1.0, dt_out: 0.01, solver: RK45, rtol: 1.0e-6, atol: 1.0e-9}
    """)


def main() -> None:
    from multipole.simulate import simulate
    from multipole.sweep import Study, _worker_model
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    folder = Path(tempfile.mkdtemp())
    path = folder / "damped_oscillator.yaml"
    path.write_text(SCENE)
    specs = {"k": f"10..1000:log:{args.runs}"}
    metrics = ["spring.deflection.final", "spring.deflection.max", "body.v.rms", "spring.deflection.settling"]

    serial = Study(path, specs, metrics)
    start, cpu = time.perf_counter(), time.process_time()
    serial.run("serial")
    t_serial, c_serial = time.perf_counter() - start, time.process_time() - cpu
    # the same solves without the study around them: every 10th run of the design (a systematic
    # sample over the whole range: stiffer runs take more steps), parameters set as the study sets them
    group = serial.groups[0]
    model = _worker_model(group.job["source"], group.job["meta"])
    o = serial.options
    sample = range(0, args.runs, 10)
    t0, cpu = time.perf_counter(), time.process_time()
    for k in sample:
        model.set_parameters(group.vectors[k])
        simulate(model, o["t_end"], o.get("dt_out"), o.get("solver", "auto"), o.get("rtol", 1e-6),
                 o.get("atol", 1e-9), progress=False)
    solve = (time.perf_counter() - t0) / len(sample)
    c_solve = (time.process_time() - cpu) / len(sample)
    per_run = t_serial / args.runs
    print(f"scene: {serial.base.name}, {args.runs} runs, {len(serial.groups)} compile(s) "
          f"({serial.compile_time:.2f} s)")
    print(f"serial: {t_serial:.2f} s, {1e3 * per_run:.2f} ms per run; one solve alone {1e3 * solve:.2f} ms "
          f"-> per-run cost {per_run / solve:.2f}x the solve")
    print(f"  CPU time of this process: {1e3 * c_serial / args.runs:.2f} ms per run, one solve alone "
          f"{1e3 * c_solve:.2f} ms -> {c_serial / args.runs / c_solve:.2f}x (less sensitive to other load)")
    print(f"  (one solve: set_parameters + simulate, mean over {len(sample)} runs of the design; the study's "
          f"time includes its analysis and code generation)")

    process = Study(path, specs, metrics)
    start = time.perf_counter()
    process.run("process", workers=args.workers)
    t_process = time.perf_counter() - start
    print(f"process pool, {args.workers} workers: {t_process:.2f} s (pool start-up included), "
          f"speed-up {t_serial / t_process:.2f}x")
    same = [r["spring.deflection.final"] for r in serial.rows] == [r["spring.deflection.final"] for r in process.rows]
    print(f"  same metrics as serial, bit for bit: {same}")
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        print("dask.distributed not installed: LocalCluster skipped (pip install multipole[cluster])")
        return
    from multipole.sweep import _Executor
    start = time.perf_counter()
    with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=None) as cl, \
            Client(cl) as client:
        t_up = time.perf_counter() - start
        dask = Study(path, specs, metrics)
        t1 = time.perf_counter()
        dask.run(_Executor(client.get_executor(), args.workers))
        t_dask = time.perf_counter() - t1
    same = [r["spring.deflection.final"] for r in serial.rows] == [r["spring.deflection.final"] for r in dask.rows]
    print(f"dask LocalCluster, {args.workers} worker processes: cluster start {t_up:.2f} s, study {t_dask:.2f} s "
          f"({t_dask / t_process:.2f}x the process pool's time, {1e3 * (t_dask - t_process) / args.runs:+.2f} ms "
          f"per run); same metrics: {same}")


if __name__ == "__main__":
    main()
