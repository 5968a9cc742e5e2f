"""Hand-offs to the engineer's tools (issue 16, parts 2 and 3): python-control, pandas, xarray, CSV
with units, notebook representations, and the figures of multipole.plotting."""
from __future__ import annotations

import csv
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import multipole
from multipole import pipeline
from multipole.cli import main
from multipole.errors import MultipoleError
from multipole.simulate import Result

ROOT = Path(__file__).resolve().parents[1]

DRIVE = ROOT / "diagrams" / "drive_train.yaml"
# drive_train.yaml: J1 = 2e-3, J2 = 0.5 kg m^2, gear i = 3, shaft c = 2000 N m/rad, d_s = 0.5, bearing d_b = 0.8
J1, J2, I_GEAR, C_SHAFT, D_S, D_B = 2e-3, 0.5, 3.0, 2000.0, 0.5, 0.8

#: a rotor braked by a cubic damper, torque f + f^3 [N m] at f [rad/s], driven by 2 N m: it settles
#: where 2 = w + w^3, i.e. w = 1 rad/s; d(p')/dp = -(1 + 3 w^2)/J
CUBIC = """\
name: cubic_brake
elements:
  drive:   {type: torque_source, value: "2.0"}
  rotor:   {type: inertia, J: 0.01}
  brake:   {type: damper, law: "f + f**3"}
  housing: {type: ground}
connections:
  - [drive.p, rotor.a]
  - [rotor.b, brake.a]
  - [brake.b, housing.p]
outputs: [rotor.omega, brake.force]
simulate: {t_end: 1.0, dt_out: 0.01, rtol: 1.0e-10, atol: 1.0e-12}
"""


def write(tmp_path, text, name="scene.yaml") -> str:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return str(path)


@pytest.fixture(scope="module")
def drive_result():
    return pipeline.run(multipole.load(DRIVE), t_end=0.01, dt_out=1e-4, progress=False)


# ------------------------------------------------------------------------------------------------
# python-control

def test_statespace_is_the_drive_trains_closed_form_with_the_scenes_names():
    """States p1 = J1 w1, q (shaft twist), p2 = J2 w2; the shaft torque is c q + d_s (w1/i - w2):
    p1' = u - T/i, q' = w1/i - w2, p2' = T - d_b w2."""
    sys_ = multipole.linearize(multipole.load(DRIVE))
    A = np.array([[-D_S / (I_GEAR ** 2 * J1), -C_SHAFT / I_GEAR, D_S / (I_GEAR * J2)],
                  [1 / (I_GEAR * J1), 0.0, -1 / J2],
                  [D_S / (I_GEAR * J1), C_SHAFT, -(D_S + D_B) / J2]])
    C = np.array([[1 / J1, 0, 0], [0, 0, 1 / J2], [0, C_SHAFT, 0]])
    assert np.allclose(sys_.A, A, rtol=1e-12, atol=0)
    assert np.allclose(sys_.B, [[1.0], [0.0], [0.0]], rtol=1e-12, atol=0)
    assert np.allclose(sys_.C, C, rtol=1e-12, atol=0) and not np.any(sys_.D)
    assert sys_.state_labels == ["rotor.p", "shaft.q", "load.p"]
    assert sys_.input_labels == ["motor:u"]              # the ground (housing) is not an input
    assert sys_.output_labels == ["rotor:omega", "load:omega", "shaft:force"]
    assert sys_.name == "drive_train"
    assert multipole.control_name("rotor.omega") == "rotor:omega"


def test_a_speed_loop_closed_with_control_interconnect():
    """PI speed controller on the rotor: the loop assembled by python-control has the poles of the
    matrix written by hand, [[A - B kp c, B ki], [-c, 0]], and a static gain of 1 (integral action)."""
    import control
    drive = multipole.linearize(multipole.load(DRIVE))
    kp, ki = 0.05, 0.5
    pi = control.ss(0.0, 1.0, ki, kp, inputs="e", outputs="motor:u", name="pi")
    error = control.summing_junction(inputs=["r", "-rotor:omega"], output="e", name="error")
    loop = control.interconnect([drive, pi, error], inplist=["r"], outlist=["rotor:omega"], check_unused=False)
    A, B, c = drive.A, drive.B, drive.C[[0]]
    hand = np.block([[A - B @ (kp * c), B * ki], [-c, np.zeros((1, 1))]])
    assert np.allclose(np.sort_complex(loop.poles()), np.sort_complex(np.linalg.eigvals(hand)), rtol=1e-9)
    assert np.all(loop.poles().real < 0)
    assert control.dcgain(loop) == pytest.approx(1.0, rel=1e-9)


def test_operating_point_given_or_simulated(tmp_path):
    J = 0.01
    scene = multipole.load(write(tmp_path, CUBIC))
    assert multipole.linearize(scene).A[0, 0] == pytest.approx(-1 / J, rel=1e-12)          # at w = 0
    w = 0.5
    assert multipole.linearize(scene, at={"rotor.p": J * w}).A[0, 0] == pytest.approx(-(1 + 3 * w ** 2) / J,
                                                                                       rel=1e-12)
    # after 1 s (400 time constants) the rotor has settled at w = 1 rad/s: A = -(1 + 3)/J
    settled = multipole.linearize(scene, at=np.int64(1))          # any real number of seconds
    assert settled.A[0, 0] == pytest.approx(-4 / J, rel=1e-6)
    assert settled.input_labels == ["drive:u"]


@pytest.mark.parametrize("at, code", [({"rotor.q": 1.0}, "unknown_state"), (-1.0, "bad_operating_point"),
                                      ("soon", "bad_operating_point"), (float("nan"), "bad_operating_point")])
def test_a_bad_operating_point_is_refused(tmp_path, at, code):
    with pytest.raises(MultipoleError) as exc:
        multipole.linearize(multipole.load(write(tmp_path, CUBIC)), at=at)
    assert exc.value.code == code


def test_cli_linearize_at_a_time(tmp_path, capsys):
    assert main(["linearize", write(tmp_path, CUBIC), "--at", "1.0"]) == 0
    out = capsys.readouterr().out
    assert "linearised at t = 1 s about the simulated state" in out
    assert "columns drive.u" in out and "housing.u" not in out


# ------------------------------------------------------------------------------------------------
# pandas, xarray, CSV

def test_to_pandas_has_a_time_index_and_units(drive_result):
    df = drive_result.to_pandas()
    assert df.index.name == "t" and np.array_equal(df.index.to_numpy(), drive_result.t)
    assert list(df.columns) == ["rotor.omega", "load.omega", "shaft.force"]
    for name in df.columns:
        assert np.array_equal(df[name].to_numpy(), drive_result[name])
    assert df.attrs["units"] == {"t": "s", "rotor.omega": "rad/s", "load.omega": "rad/s", "shaft.force": "N*m"}


def test_to_xarray_has_units_on_every_variable(drive_result):
    pytest.importorskip("xarray")
    ds = drive_result.to_xarray()
    assert ds["t"].attrs["units"] == "s" and ds["shaft.force"].attrs["units"] == "N*m"
    assert np.array_equal(ds["rotor.omega"].to_numpy(), drive_result["rotor.omega"])


def test_to_xarray_without_xarray_names_what_to_install(drive_result, monkeypatch):
    monkeypatch.setitem(sys.modules, "xarray", None)          # import xarray now raises ImportError
    with pytest.raises(MultipoleError) as exc:
        drive_result.to_xarray()
    assert exc.value.code == "missing_package" and "multipole[xarray]" in exc.value.fix


def test_simulate_csv_has_units_and_reads_back(tmp_path, capsys):
    out = tmp_path / "r.csv"
    assert main(["simulate", str(DRIVE), "--t-end", "0.01", "--dt-out", "0.001", "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()
    header = next(csv.reader(out.open()))
    assert header == ["t [s]", "rotor.omega [rad/s]", "load.omega [rad/s]", "shaft.force [N*m]"]
    df = multipole.read_csv(out)
    ref = pipeline.run(multipole.load(DRIVE), t_end=0.01, dt_out=0.001, progress=False).to_pandas()
    assert list(df.columns) == list(ref.columns) and df.attrs["units"] == ref.attrs["units"]
    assert np.allclose(df.index.to_numpy(), ref.index.to_numpy(), rtol=1e-11, atol=0)
    # the CSV keeps 12 significant digits
    assert np.allclose(df.to_numpy(), ref.to_numpy(), rtol=1e-11, atol=1e-11 * np.abs(ref.to_numpy()).max())


# ------------------------------------------------------------------------------------------------
# notebook representations

def _many_outputs(n=40):
    t = np.linspace(0, 1e-3, 101)
    outs = {f"mesh{k}.force": np.sin(k * t) for k in range(n)}
    return Result(t, outs, np.zeros((len(t), n)), [f"s{k}.q" for k in range(n)], "RK45", "non-stiff: " + "x" * 500,
                  {"steps": 12, "warnings": ["overflow in exp"]}, [], {n_: "N" for n_ in outs})


def test_result_repr_is_short_and_says_what_is_inside(drive_result):
    text = repr(drive_result)
    assert text.startswith("<Result t = 0 … 10 ms, 101 samples") and "shaft.force [N*m]" in text
    assert "3 state(s)" in text and f"solver {drive_result.solver}" in text
    big = repr(_many_outputs())
    assert len(big.encode()) < 1000 and "(32 more)" in big and "1 warning(s)" in big


def test_result_html_lists_outputs_states_and_solver(drive_result):
    html = drive_result._repr_html_()
    for word in ("rotor.omega", "rad/s", "N*m", "rotor.p", drive_result.summary()):
        assert word in html
    final = drive_result["shaft.force"][-1]
    assert f"<td>{final:.6g}</td>" in html
    assert "overflow in exp" in _many_outputs()._repr_html_()
    html = _many_outputs(60)._repr_html_()
    assert html.count("<tr>") == 1 + 50 + 1 and "… 10 more outputs" in html and len(html) < 10_000


def test_analysis_repr_is_short():
    well = pipeline.check(multipole.load(DRIVE))
    assert repr(well) == "<Analysis well-posed: 0 error(s), 0 warning(s); 3 state(s): rotor.p, shaft.q, load.p>"
    bad = pipeline.check(multipole.load(ROOT / "diagrams" / "power_split_rigid.yaml"))
    text = repr(bad)
    assert text.startswith("<Analysis NOT well-posed: 1 error(s)") and "kinematic_overdetermination" in text
    assert len(text) < 1000
    html = bad._repr_html_()
    assert "kinematic_overdetermination" in html and "make one coupling in this loop elastic" in html


# ------------------------------------------------------------------------------------------------
# figures

@pytest.mark.parametrize("t_end, scale, unit", [(2.0, 1.0, "s"), (1.0, 1.0, "s"), (0.1, 1e-3, "ms"),
                                                (0.00025, 1e-6, "µs"), (5e-8, 1e-9, "ns")])
def test_time_axis_unit(t_end, scale, unit):
    from multipole.plotting import time_unit
    assert time_unit(t_end) == (scale, unit)


def test_time_plot_axes_are_scaled_and_labelled(drive_result, tmp_path):
    import matplotlib
    import matplotlib.pyplot as plt
    backend, figures = matplotlib.get_backend(), plt.get_fignums()
    fig = drive_result.plot(tmp_path / "r.png", title="drive")
    assert (tmp_path / "r.png").stat().st_size > 10_000
    axes = fig.axes
    assert axes[-1].get_xlabel() == "t [ms]" and axes[-1].get_xlim() == pytest.approx((0.0, 10.0))
    assert [ax.get_ylabel() for ax in axes] == ["rotor.omega [rad/s]", "load.omega [rad/s]", "shaft.force [N*m]"]
    assert matplotlib.get_backend() == backend and plt.get_fignums() == figures   # nothing left in pyplot


def test_bode_has_one_column_per_unit_and_legends_off_the_curves(tmp_path):
    import matplotlib.pyplot as plt
    from multipole.linearize import scene_linearization
    from multipole.plotting import bode
    figures = plt.get_fignums()
    fig = bode(scene_linearization(multipole.load(DRIVE)), tmp_path / "b.png", "drive_train")
    assert (tmp_path / "b.png").stat().st_size > 10_000 and plt.get_fignums() == figures
    axes = fig.axes
    labels = sorted(ax.get_ylabel() for ax in axes)
    assert labels == ["phase [deg]", "phase [deg]", "|G| [(rad/s)/(N*m)]", "|G| [-]"]
    assert all(ax.get_xlabel() == "frequency [Hz]" for ax in axes if ax.get_ylabel() == "phase [deg]")
    curves = [line.get_label() for ax in axes for line in ax.get_lines() if not line.get_label().startswith("_")]
    assert sorted(curves) == ["motor.u → load.omega", "motor.u → rotor.omega", "motor.u → shaft.force"]
    # savefig drew the figure: the constrained layout has placed every axes and legend
    renderer = fig.canvas.get_renderer()
    legends = [ax.get_legend() for ax in axes if ax.get_legend() is not None]
    assert len(legends) == 2
    for legend in legends:
        box = legend.get_window_extent(renderer)
        assert not any(box.overlaps(ax.get_window_extent(renderer)) for ax in axes)


def test_plot_without_a_file_is_a_pyplot_figure_for_the_notebook(drive_result):
    """Without a path the figure is made by pyplot, so the user's backend (inline in a notebook)
    shows it; the backend itself is not switched."""
    import matplotlib
    import matplotlib.pyplot as plt
    backend = matplotlib.get_backend()
    fig = drive_result.plot()
    try:
        assert fig.number in plt.get_fignums() and matplotlib.get_backend() == backend
    finally:
        plt.close(fig)


def test_time_plot_compares_runs_with_a_legend_off_the_curves(drive_result, tmp_path):
    """A full and a coarse run on one figure (how a reduced model or a second solver is shown)."""
    from multipole.plotting import time_plot
    coarse = pipeline.run(multipole.load(DRIVE), t_end=0.01, dt_out=1e-3, solver="RK23", rtol=1e-3, progress=False)
    fig = time_plot({"full": drive_result, "coarse": coarse}, tmp_path / "c.png", "two runs", footer="compared")
    assert all(len(ax.get_lines()) == 2 for ax in fig.axes)
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == ["full", "coarse"]
    # savefig drew the figure: the constrained layout has placed every axes and legend
    renderer = fig.canvas.get_renderer()
    box = fig.axes[0].get_legend().get_window_extent(renderer)
    assert not any(box.overlaps(ax.get_window_extent(renderer)) for ax in fig.axes)
    assert not box.overlaps(fig._suptitle.get_window_extent(renderer))


def test_bode_of_many_unit_pairs_wraps_into_rows_without_overlaps(tmp_path):
    """A voltage and a torque driving a speed and a current (one state, x' = -x + u1 + u2): four
    (output unit, input unit) pairs, three columns a row, nothing drawn over anything else."""
    from multipole.linearize import Linearization
    from multipole.plotting import BODE_COLUMNS, bode
    lin = Linearization(np.array([[-1.0]]), np.array([[1.0, 1.0]]), np.array([[1.0], [2.0]]), np.zeros((2, 2)),
                        ["m.p"], ["supply.u", "brake.u"], ["m.omega", "m.current"],
                        {"supply.u": "V", "brake.u": "N*m", "m.omega": "rad/s", "m.current": "A"})
    fig = bode(lin, tmp_path / "b.png")
    shown = [ax for ax in fig.axes if ax.get_visible()]
    assert len(shown) == 2 * 4 and len(fig.axes) == 2 * 2 * BODE_COLUMNS
    assert sorted(ax.get_ylabel() for ax in shown if ax.get_ylabel().startswith("|G|")) == \
        ["|G| [(rad/s)/(N*m)]", "|G| [(rad/s)/V]", "|G| [A/(N*m)]", "|G| [A/V]"]
    # savefig drew the figure: the constrained layout has placed every axes and legend
    renderer = fig.canvas.get_renderer()
    boxes = [ax.get_window_extent(renderer) for ax in shown]
    boxes += [ax.get_legend().get_window_extent(renderer) for ax in shown if ax.get_legend() is not None]
    assert len(boxes) == 8 + 4
    assert not any(a.overlaps(b) for k, a in enumerate(boxes) for b in boxes[k + 1:])
    phase = [ax for ax in shown if ax.get_ylabel() == "phase [deg]"]
    assert all(any(t.get_text() for t in ax.get_xticklabels()) for ax in phase)    # frequencies readable


def test_the_package_never_switches_the_matplotlib_backend():
    """No module of the kernel or the element library selects a backend (the user's stays)."""
    sources = [p for folder in ("multipole", "elements") for p in (ROOT / folder).rglob("*.py")]
    assert len(sources) > 20
    for path in sources:
        text = path.read_text(encoding="utf-8")
        for call in ("matplotlib.use(", "switch_backend(", "mpl.use("):
            assert call not in text, f"{path.relative_to(ROOT)} calls {call}"


def test_not_linearizable_at_the_given_point_names_the_element(tmp_path):
    """torque sqrt(|f|): smooth while the rotor turns (omega0 = 1), infinite slope at standstill;
    the error names the brake (found by evaluating the compiled Jacobian at that point)."""
    text = CUBIC.replace('"f + f**3"', '"sqrt(abs(f))"').replace("J: 0.01}", "J: 0.01, omega0: 1.0}")
    scene = multipole.load(write(tmp_path, text))
    assert multipole.linearize(scene).A[0, 0] == pytest.approx(-0.5 / 0.01, rel=1e-12)   # d sqrt(w)/dw = 1/2
    with pytest.raises(multipole.RunError) as exc:
        multipole.linearize(scene, at={"rotor.p": 0.0})
    assert exc.value.code == "not_linearizable" and "element 'brake'" in exc.value.where
    assert "about the given state" in exc.value.message
