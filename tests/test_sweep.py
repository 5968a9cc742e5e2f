"""Parameter studies (multipole/sweep.py, docs/sweeps.md): SPECs, designs, metrics against closed
forms, runtime parameters against the oscillator's analytic solution, failed runs as rows, the
same table (bit for bit) on every executor, and the command line's errors."""
from __future__ import annotations

import csv
import math
import textwrap

import numpy as np
import pytest

from multipole.cli import main
from multipole.errors import MultipoleError
from multipole.netlist import loads
from multipole.sweep import (SerialExecutor, Study, _Executor, design, make_executor, parse_spec,
                             reduce_output)

# A mass on a spring started at x0: q(t) = x0*cos(w*t), w = sqrt(c/m).  ``c`` is computed from the
# scene parameter ``k`` (c2 = 2*k), so a study of k also tests that dependent parameters follow.
OSCILLATOR = textwrap.dedent("""\
    name: oscillator
    parameters: {k: 2.0, c2: "2*k", x0: 0.1, mm: 1.0}
    elements:
      body:   {type: mass, m: mm}
      spring: {type: spring, c: c2, x0: x0, domain: translational}
      wall:   {type: ground, domain: translational}
    connections:
      - [wall.p, spring.a]
      - [spring.b, body.a]
    outputs: [spring.deflection, body.v]
    metrics:
      peak_to_peak: "spring.deflection.max - spring.deflection.min"
      energy_end: "0.5*body.v.final**2"
    simulate: {t_end: 1.0, dt_out: 0.01, solver: DOP853, rtol: 1.0e-10, atol: 1.0e-13}
    """)
RTOL = 1e-10


@pytest.fixture
def oscillator(tmp_path):
    path = tmp_path / "oscillator.yaml"
    path.write_text(OSCILLATOR)
    return path


def _q(t, c, m, x0=0.1):
    """The oscillator's deflection: the spring is stretched by x0 at t = 0 and the mass starts at rest."""
    return x0 * np.cos(np.sqrt(c / m) * t)


# -- SPECs ------------------------------------------------------------------------------------------
def test_spec_list_range_and_distributions():
    assert parse_spec("c", "1e7,2e7").values == (1e7, 2e7)
    lin = parse_spec("d", "0..1:lin:11")
    assert lin.kind == "range" and len(lin.values) == 11
    np.testing.assert_allclose(lin.values, [k / 10 for k in range(11)], rtol=0, atol=1e-15)
    log = parse_spec("c", "1..1000:log:4")
    np.testing.assert_allclose(log.values, [1.0, 10.0, 100.0, 1000.0], rtol=1e-14)
    assert log.scale == "log"
    assert parse_spec("c", "normal(2e8, 1e7)").args == (2e8, 1e7)
    assert parse_spec("c", "uniform(1, 2)").args == (1.0, 2.0)
    assert parse_spec("w", "2*pi, 4*pi").values == pytest.approx((2 * math.pi, 4 * math.pi), rel=1e-15)
    assert parse_spec("mesh.level", "ideal,elastic").values == ("ideal", "elastic")


@pytest.mark.parametrize("text", ["1..2", "1..2:cubic:3", "0..1:log:3", "1..2:lin:0", "normal(1)",
                                  "normal(1, -1)", "uniform(2, 1)", "1e7,,2e7", "__import__('os')",
                                  "2**", "1..x:lin:3", "", "exp(1000)..1:lin:2", "normal(a, 1)"])
def test_malformed_specs_are_bad_spec(text):
    with pytest.raises(MultipoleError) as exc:
        parse_spec("c", text)
    assert exc.value.code == "bad_spec"
    assert exc.value.exit_code == 2


def test_grid_rows_first_parameter_slowest():
    rows = design([parse_spec("a", "1,2"), parse_spec("b", "10,20,30")])
    assert rows == [{"a": 1.0, "b": 10.0}, {"a": 1.0, "b": 20.0}, {"a": 1.0, "b": 30.0},
                    {"a": 2.0, "b": 10.0}, {"a": 2.0, "b": 20.0}, {"a": 2.0, "b": 30.0}]


def test_grid_refuses_distributions():
    with pytest.raises(MultipoleError) as exc:
        design([parse_spec("a", "normal(1, 0.1)")])
    assert exc.value.code == "bad_design"


def test_samples_reproducible_with_seed():
    specs = [parse_spec("a", "normal(5, 0.5)"), parse_spec("b", "uniform(2, 3)"), parse_spec("c", "1,2,3")]
    first, again, other = design(specs, 400, 7), design(specs, 400, 7), design(specs, 400, 8)
    assert first == again
    assert first != other
    a = np.array([r["a"] for r in first])
    b = np.array([r["b"] for r in first])
    assert abs(a.mean() - 5) < 5 * 0.5 / math.sqrt(400)          # five standard errors
    assert b.min() >= 2 and b.max() < 3
    assert {r["c"] for r in first} == {1.0, 2.0, 3.0}


# -- metrics against closed forms -----------------------------------------------------------------
def test_reductions_closed_forms():
    t = np.linspace(0, 2 * np.pi, 20001)
    y = np.sin(t)
    h = t[1] - t[0]
    assert reduce_output(t, y, "rms") == pytest.approx(1 / math.sqrt(2), abs=h ** 2)   # trapezoid error O(h²)
    assert reduce_output(t, y, "mean") == pytest.approx(0.0, abs=h ** 2)
    assert reduce_output(t, y, "max") == pytest.approx(1.0, abs=h ** 2)
    assert reduce_output(t, y, "min") == pytest.approx(-1.0, abs=h ** 2)
    assert reduce_output(t, y, "final") == y[-1]
    tau = 0.5
    t = np.linspace(0, 10, 10001)
    step = 1 - np.exp(-t / tau)
    # within 2 % of the total change from tau*ln(1/0.02) on, up to the grid and the final value's offset
    expected = tau * math.log((1 - math.exp(-10 / tau)) / 0.02)
    assert reduce_output(t, step, "settling") == pytest.approx(expected, abs=t[1] - t[0])


def test_settling_nan_when_it_never_settles():
    t = np.linspace(0, 10, 1001)
    assert math.isnan(reduce_output(t, np.sin(5 * t) * t, "settling"))


# -- studies --------------------------------------------------------------------------------------------
def test_runtime_parameters_match_the_closed_form(oscillator):
    """One compiled model, parameters set per run: every row's final deflection is the oscillator's
    at its own k (through the dependent c2 = 2k) and its own body mass (an element parameter)."""
    study = Study(oscillator, {"k": "1..50:log:4", "mm": "0.5,2", "x0": "0.1,-0.05"},
                  metrics=["spring.deflection.final", "spring.deflection.max"])
    rows = study.run(SerialExecutor())
    assert len(study.groups) == 1 and study.kinds == {"k": "runtime", "mm": "runtime", "x0": "runtime"}
    assert len(rows) == 16 and all(r["status"] == "ok" for r in rows)
    for r in rows:
        expected = _q(1.0, 2 * r["k"], r["mm"], r["x0"])        # the initial state follows x0 too
        assert r["spring.deflection.final"] == pytest.approx(expected, abs=1e-7)
        if r["x0"] > 0:
            assert r["spring.deflection.max"] == pytest.approx(r["x0"], abs=1e-9)   # at t = 0
        assert 0 < r["nfev"] and r["steps"] >= 1


def test_element_parameter_is_a_runtime_value(oscillator):
    study = Study(oscillator, {"body.m": "0.5,1,4"}, metrics=["spring.deflection.final"])
    rows = study.run(SerialExecutor())
    assert study.kinds["body.m"] == "runtime" and len(study.groups) == 1
    for r in rows:
        assert r["spring.deflection.final"] == pytest.approx(_q(1.0, 4.0, r["body.m"]), abs=1e-7)


def test_named_metrics_from_the_netlist(oscillator):
    # w = 2*pi and 4*pi: the grid (dt 0.01) holds the half periods, so peak to peak is 2*x0, and
    # after whole periods the mass is at rest again (energy 0)
    study = Study(oscillator, {"k": [2 * math.pi ** 2, 8 * math.pi ** 2]}, metrics=["peak_to_peak", "energy_end"])
    for r in study.run(SerialExecutor()):
        assert r["peak_to_peak"] == pytest.approx(0.2, abs=1e-8)
        assert r["energy_end"] == pytest.approx(0.0, abs=1e-12)


def test_structural_parameter_compiles_once_per_group(tmp_path):
    path = tmp_path / "gear.yaml"
    path.write_text(textwrap.dedent("""\
        name: gear
        parameters: {r1: 0.02, r2: 0.06}
        elements:
          motor:  {type: torque_source, value: "5*step(t)"}
          pinion: {type: inertia, J: 1.0e-3}
          mesh:   {type: spur_stage, r1: r1, r2: r2, level: elastic, c: 2.0e8}
          wheel:  {type: inertia, J: 2.0e-2}
        connections:
          - [motor.p, pinion.a]
          - [pinion.b, mesh.a]
          - [mesh.b, wheel.a]
        outputs: [wheel.omega]
        simulate: {t_end: 0.01, dt_out: 1.0e-4, rtol: 1.0e-10, atol: 1.0e-12}
        """))
    study = Study(path, {"mesh.level": "ideal,elastic", "r2": "0.04,0.06"}, metrics=["wheel.omega.final"])
    rows = study.run(SerialExecutor())
    assert study.kinds == {"mesh.level": "structural", "r2": "runtime"}
    assert len(study.groups) == 2
    # level ideal refuses the mesh stiffness c: a group that cannot be built is rows with the
    # loader's diagnostic, not a crashed study
    assert [r["status"] for r in rows] == ["failed", "failed", "ok", "ok"]
    assert all("bad_parameter" in r["diagnostic"] for r in rows[:2])
    for r in rows[2:]:
        # the mean speed after the torque step follows the total inertia seen at the wheel,
        # omega_w = M*i*t/(J1*i² + J2), i = r2/r1; the elastic mesh adds a ringing of a few per cent
        i = r["r2"] / 0.02
        mean = 5 * i * 0.01 / (1e-3 * i ** 2 + 2e-2)
        assert abs(r["wheel.omega.final"]) == pytest.approx(mean, rel=0.03)


def test_failing_variant_is_a_row(oscillator):
    """A zero mass (a scene parameter, so the loader cannot refuse it for the element) divides by
    zero in the model: that run is a failed row with its diagnostic, the others are ok; a value the
    element refuses (a negative mass given to body.m) is an invalid row."""
    study = Study(oscillator, {"mm": "1,0,2"}, metrics=["spring.deflection.final"])
    rows = study.run(SerialExecutor())
    assert [r["status"] for r in rows] == ["ok", "failed", "ok"]
    assert rows[1]["diagnostic"].startswith("error[") and math.isnan(rows[1]["spring.deflection.final"])
    assert study.failed == 1
    rows = Study(oscillator, {"body.m": "1,-1"}, metrics=["spring.deflection.final"]).run(SerialExecutor())
    assert [r["status"] for r in rows] == ["ok", "invalid"]
    assert "bad_value" in rows[1]["diagnostic"]


def test_unknown_parameter_and_metric(oscillator):
    for name, code in (("nope", "unknown_parameter"), ("body.nope", "unknown_parameter"),
                       ("nobody.m", "unknown_parameter")):
        with pytest.raises(MultipoleError) as exc:
            Study(oscillator, {name: "1,2"})
        assert exc.value.code == code and exc.value.exit_code == 2
    with pytest.raises(MultipoleError) as exc:
        Study(oscillator, {"k": "1,2"}, metrics=["spring.deflection.median"])
    assert exc.value.code == "unknown_metric"


def test_interrupt_keeps_finished_rows(oscillator):
    def progress(done, failed, total, eta):
        if done >= 3:
            raise KeyboardInterrupt
    study = Study(oscillator, {"k": "1..10:lin:8"}, metrics=["spring.deflection.final"])
    rows = study.run(SerialExecutor(), progress=progress, chunk=1)
    assert study.interrupted
    assert 3 <= len(rows) < 8 and [r["run"] for r in rows] == list(range(len(rows)))
    for r in rows:
        assert r["spring.deflection.final"] == pytest.approx(_q(1.0, 2 * r["k"], 1.0), abs=1e-7)


def test_api_returns_a_dataframe(oscillator):
    import multipole
    import pandas as pd
    df = multipole.sweep(oscillator, {"k": "1,2"}, metrics=["spring.deflection.final"], executor="serial")
    assert isinstance(df, pd.DataFrame)
    assert list(df.columns[:3]) == ["run", "k", "spring.deflection.final"]
    assert list(df["status"]) == ["ok", "ok"]


def _table(study):
    names = [m.name for m in study.metrics]
    return [(r["run"], r["status"], tuple(r[n] for n in names)) for r in study.rows]


def _same(a, b):
    """Bit for bit, NaN equal to NaN."""
    return len(a) == len(b) and all(ra[:2] == rb[:2] and all(x == y or (math.isnan(x) and math.isnan(y))
                                                            for x, y in zip(ra[2], rb[2])) for ra, rb in zip(a, b))


def test_identical_tables_serial_process_dask(oscillator):
    """The same study gives the same metrics, bit for bit, in this process, on a process pool and
    on a real dask.distributed LocalCluster of two worker processes (a failing run included)."""
    specs = {"k": "1..30:lin:5", "mm": "1,0,3"}
    metrics = ["spring.deflection.final", "spring.deflection.rms", "peak_to_peak"]
    serial = Study(oscillator, specs, metrics)
    serial.run("serial")
    process = Study(oscillator, specs, metrics)
    process.run("process", workers=2, chunk=2)
    assert _same(_table(serial), _table(process))
    assert sum(r["status"] != "ok" for r in serial.rows) == 5
    pytest.importorskip("dask.distributed", reason="dask[distributed] is not installed (pip install multipole[cluster])")
    from dask.distributed import Client, LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        dask = Study(oscillator, specs, metrics)
        dask.run(_Executor(client.get_executor(), 2), chunk=3)
    assert _same(_table(serial), _table(dask))
    shuffled = Study(oscillator, specs, metrics)       # another chunking: still the same numbers
    shuffled.run("serial", chunk=4)
    assert _same(_table(serial), _table(shuffled))


def test_unreachable_scheduler_is_a_clear_error():
    pytest.importorskip("dask.distributed", reason="dask[distributed] is not installed")
    with pytest.raises(MultipoleError) as exc:
        make_executor("dask", scheduler="tcp://127.0.0.1:9", timeout=1.0)
    assert exc.value.code == "scheduler_unreachable"
    assert "tcp://127.0.0.1:9" in exc.value.message


# -- the netlist's metrics: section ----------------------------------------------------------------
@pytest.mark.parametrize("section, code", [("metrics: [a]", "bad_metric"),
                                           ("metrics: {2x: \"body.v.max\"}", "bad_metric"),
                                           ("metrics: {m: \"wheel.v.max\"}", "unsafe_expression"),
                                           ("metrics: {m: \"body.v.median\"}", "unknown_name"),
                                           ("metrics: {m: \"__import__('os')\"}", "unsafe_expression")])
def test_metrics_section_errors(section, code):
    start, end = OSCILLATOR.index("metrics:"), OSCILLATOR.index("simulate:")
    text = OSCILLATOR[:start] + section + "\n" + OSCILLATOR[end:]
    with pytest.raises(MultipoleError) as exc:
        loads(text, "m.yaml")
    assert exc.value.code == code
    assert "m.yaml:" in exc.value.where


# -- command line ------------------------------------------------------------------------------------
def test_cli_writes_table_figure_and_summary(oscillator, tmp_path, capsys):
    out = tmp_path / "study"
    code = main(["sweep", str(oscillator), "--set", "k=1,4", "--set", "mm=1,0", "--executor", "serial",
                 "--metrics", "spring.deflection.final,peak_to_peak", "-o", str(out), "--quiet"])
    assert code == 3                                      # some runs failed (mm = 0)
    with open(out / "runs.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["status"] for r in rows] == ["ok", "failed", "ok", "failed"]
    assert float(rows[2]["spring.deflection.final"]) == pytest.approx(_q(1.0, 8.0, 1.0), abs=1e-7)
    assert (out / "figure.png").stat().st_size > 0 and (out / "summary.txt").exists()
    assert "2 failed" in capsys.readouterr().out


@pytest.mark.parametrize("argv, code", [(["--set", "nope=1,2"], "unknown_parameter"),
                                        (["--set", "k=1..2"], "bad_spec"),
                                        (["--set", "k=normal(1, 0.1)"], "bad_design"),
                                        (["--set", "k=1..2:lin:5", "--confirm", "4"], "too_many_runs"),
                                        (["--set", "k=1,2", "--plot-metric", "x.max"], "unknown_metric"),
                                        (["--set", "k=1,2", "--scheduler", "tcp://127.0.0.1:9"], "bad_option")])
def test_cli_bad_input_exit_2(oscillator, tmp_path, capsys, argv, code):
    assert main(["sweep", str(oscillator), "-o", str(tmp_path / "o"), "--quiet"] + argv) == 2
    assert f"error[{code}]" in capsys.readouterr().err


def test_cli_confirm_with_yes(oscillator, tmp_path):
    assert main(["sweep", str(oscillator), "--set", "k=1..2:lin:5", "--confirm", "4", "--yes", "--executor",
                 "serial", "-o", str(tmp_path / "o"), "--quiet"]) == 0


def test_cli_samples_reproducible(oscillator, tmp_path):
    tables = []
    for k in range(2):
        out = tmp_path / f"o{k}"
        assert main(["sweep", str(oscillator), "--set", "k=uniform(1, 5)", "--samples", "4", "--seed", "3",
                     "--executor", "serial", "--metrics", "spring.deflection.final", "-o", str(out), "--quiet"]) == 0
        with open(out / "runs.csv") as fh:
            tables.append([(r["k"], r["spring.deflection.final"]) for r in csv.DictReader(fh)])
    assert tables[0] == tables[1] and len(tables[0]) == 4
    for k, final in tables[0]:
        assert float(final) == pytest.approx(_q(1.0, 2 * float(k), 1.0), abs=1e-7)


def test_cli_unreachable_scheduler_exit_2(oscillator, tmp_path, capsys):
    pytest.importorskip("dask.distributed", reason="dask[distributed] is not installed")
    assert main(["sweep", str(oscillator), "--set", "k=1,2", "--executor", "dask", "--scheduler",
                 "tcp://127.0.0.1:9", "--timeout", "1", "-o", str(tmp_path / "o"), "--quiet"]) == 2
    assert "error[scheduler_unreachable]" in capsys.readouterr().err


def test_cli_keeps_trajectories(oscillator, tmp_path):
    out = tmp_path / "o"
    assert main(["sweep", str(oscillator), "--set", "k=2,8", "--executor", "serial", "--keep-trajectories",
                 "--metrics", "spring.deflection.final", "-o", str(out), "--quiet"]) == 0
    with open(out / "trajectories.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["run", "t", "spring.deflection", "body.v"]
    assert len(rows) == 2 * 101                          # t = 0, 0.01, ..., 1 for each run
    for r in rows:
        c = 2 * (2.0 if r["run"] == "0" else 8.0)        # c2 = 2*k, m = 1
        assert float(r["spring.deflection"]) == pytest.approx(_q(float(r["t"]), c, 1.0), abs=1e-7)


def test_lost_worker_makes_failed_rows_not_a_crash(oscillator):
    import concurrent.futures as cf
    from concurrent.futures.process import BrokenProcessPool

    class Broken(cf.Executor):
        """Every other chunk's worker dies."""
        calls = 0

        def submit(self, fn, *args, **kwargs):
            future = cf.Future()
            Broken.calls += 1
            if Broken.calls % 2:
                future.set_result(fn(*args, **kwargs))
            else:
                future.set_exception(BrokenProcessPool("a worker was killed"))
            return future

    study = Study(oscillator, {"k": "1..4:lin:4"}, metrics=["spring.deflection.final"])
    rows = study.run(_Executor(Broken(), 1), chunk=1)
    assert [r["status"] for r in rows] == ["ok", "failed", "ok", "failed"]
    assert "error[worker_failed] BrokenProcessPool" in rows[1]["diagnostic"]
    assert rows[2]["spring.deflection.final"] == pytest.approx(_q(1.0, 6.0, 1.0), abs=1e-7)


def test_cli_parquet_when_pyarrow(oscillator, tmp_path):
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow", reason="pyarrow is not installed: no Parquet table")
    out = tmp_path / "o"
    assert main(["sweep", str(oscillator), "--set", "k=2,8", "--executor", "serial",
                 "--metrics", "spring.deflection.final", "-o", str(out), "--quiet"]) == 0
    table = pd.read_parquet(out / "runs.parquet")
    assert list(table["k"]) == [2.0, 8.0]
    for k, final in zip(table["k"], table["spring.deflection.final"]):
        assert final == pytest.approx(_q(1.0, 2 * k, 1.0), abs=1e-7)


def test_progress_line(capsys):
    from multipole.sweep import _Bar
    bar = _Bar(True)
    bar(3, 1, 8, 12.4)
    bar.end()
    err = capsys.readouterr().err
    assert "runs 3/8, 1 failed, ETA 12 s" in err and err.endswith("\n")


def test_element_that_needs_a_number_is_structural():
    """piezo_stack builds n elements: n cannot stay a symbol, so each value is its own group; the
    load mass stays a runtime value of each group's model."""
    from pathlib import Path
    scene = Path(__file__).resolve().parents[1] / "diagrams" / "weber" / "piezo_stack.yaml"
    study = Study(scene, {"piezo.n": "2,3", "load.m": "0.5,1"}, metrics=["piezo.stroke.final"], t_end=1e-4)
    rows = study.run(SerialExecutor())
    assert study.kinds == {"piezo.n": "structural", "load.m": "runtime"}
    assert len(study.groups) == 2
    assert [r["status"] for r in rows] == ["ok"] * 4
    # three elements in series stretch more than two under the same voltage ramp, whatever the load
    assert rows[2]["piezo.stroke.final"] > rows[0]["piezo.stroke.final"] > 0


def test_a_run_does_not_depend_on_the_runs_before_it(tmp_path):
    """The solver choice of ``auto`` (from each run's own stiffness estimate) is made per run: a
    lightly damped run after a stiff, heavily damped one in the same worker gives the same numbers,
    bit for bit, as the light one alone."""
    path = tmp_path / "damped.yaml"
    path.write_text(textwrap.dedent("""\
        name: damped
        parameters: {dd: 0.1}
        elements:
          body:   {type: mass, m: 1.0}
          spring: {type: spring, c: 100.0, x0: 0.01, domain: translational}
          damper: {type: damper, d: dd, domain: translational}
          wall:   {type: ground, domain: translational}
        connections:
          - [wall.p, spring.a, damper.a]
          - [spring.b, damper.b, body.a]
        outputs: [spring.deflection]
        simulate: {t_end: 2.0, dt_out: 0.01, solver: auto, rtol: 1.0e-8, atol: 1.0e-12}
        """))
    metrics = ["spring.deflection.final", "spring.deflection.rms"]
    after = Study(path, {"dd": "1e6,0.1"}, metrics)
    after.run(SerialExecutor())
    alone = Study(path, {"dd": "0.1"}, metrics)
    alone.run(SerialExecutor())
    assert after.rows[0]["solver"] != alone.rows[0]["solver"]      # stiff and not: two different choices
    assert [after.rows[1][k] for k in metrics + ["solver"]] == [alone.rows[0][k] for k in metrics + ["solver"]]


def test_cli_ctrl_c_writes_the_finished_rows(oscillator, tmp_path, monkeypatch, capsys):
    from multipole import sweep as sweep_module

    def interrupt(self, done, failed, total, eta):
        if done >= 2:
            raise KeyboardInterrupt
    monkeypatch.setattr(sweep_module._Bar, "__call__", interrupt)
    out = tmp_path / "o"
    code = main(["sweep", str(oscillator), "--set", "k=1..8:lin:8", "--executor", "serial",
                 "--metrics", "spring.deflection.final", "-o", str(out), "--quiet"])
    assert code == 130
    with open(out / "runs.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert 2 <= len(rows) < 8
    for r in rows:
        assert float(r["spring.deflection.final"]) == pytest.approx(_q(1.0, 2 * float(r["k"]), 1.0), abs=1e-7)
    assert "(interrupted)" in (out / "summary.txt").read_text()
    assert "finished run(s) kept" in capsys.readouterr().err


def test_runtime_model_refuses_a_vector_of_the_wrong_length(oscillator):
    from multipole import pipeline
    from multipole.codegen import compile_model
    scene = loads(oscillator.read_text(), "oscillator.yaml")
    eq = pipeline.equations(scene)
    k = next(p for p in eq.params if str(p) == "x0")
    model = compile_model(eq, scene.outputs, [k])
    assert model.runtime == ["x0"]
    model.set_parameters([0.3])
    x0 = dict(zip(model.state_names, model.x0.tolist()))
    assert x0 == {"spring.q": 0.3, "body.p": 0.0}           # the spring starts stretched by x0, the mass at rest
    with pytest.raises(MultipoleError) as exc:
        model.set_parameters([0.3, 1.0])
    assert exc.value.code == "bad_parameters"
