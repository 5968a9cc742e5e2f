"""``multipole bench``: references, error measures, stability bounds and a tiny smoke run."""
import csv
from pathlib import Path

import numpy as np
import pytest

import multipole_models as S
from multipole import MultipoleError, NetlistError, pipeline
from multipole.bench import (SPEEDUP_TARGET, build_reference, default_scenes, explicit_stability_bound,
                             reference_spec, rk_stability_radius)
from multipole.cli import main
from multipole.netlist import loads
from multipole.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]


def test_default_scenes_are_the_bench_tagged_ones_including_the_hard_cases():
    scenes = default_scenes()
    names = [sc.name for sc in scenes]
    # bench: true, well-posed; every simulatable hard case but the 10^4-period one (benchmarks/long_horizon.py
    # studies that) and the piezo stack (a check of auto's choice, without a hand-written model in the
    # bench's states); not power_split_rigid (untagged) nor differentiated_step (expect_check)
    assert sorted(names) == sorted(["drive_train", "rlc_series", "stiff_drive_train", "mathieu", "stick_slip",
                                    "slack_rope", "slider_crank", "two_mass_oscillator", "nonlinear_loop",
                                    "toothed_belt", "compressor"])
    assert {sc.path for sc in scenes} >= {"basic:drive_train.yaml", "basic:hard/mathieu.yaml", "belts:compressor.yaml"}


def test_the_toothed_belt_of_the_default_set_reads_its_tables_from_a_private_folder_outside_the_checkout():
    from multipole.bench import hand_model
    belt = next(sc for sc in default_scenes() if sc.name == "toothed_belt")
    folder = Path(belt.path).parent
    assert not folder.resolve().is_relative_to(ROOT)                   # an installed package has no diagrams/
    for name in ("toothed_belt_wheel1.csv", "toothed_belt_wheel2.csv"):
        assert (folder / name).read_text(encoding="utf-8") == (ROOT / "diagrams" / "belts" / name).read_text(
            encoding="utf-8")
    # the scene names them relative to itself (the netlist rule: data files lie in the netlist's folder)
    assert [belt.element_values[w]["contour"] for w in ("wheel1", "wheel2")] == ["toothed_belt_wheel1.csv",
                                                                                "toothed_belt_wheel2.csv"]
    assert hand_model(belt) is not None                    # which reads them beside the scene too


def test_default_scenes_come_through_the_entry_point_group_not_the_checkout(monkeypatch):
    from importlib.metadata import entry_points

    import multipole.bench as bench
    assert any(ep.value == "multipole_models:bench_scenes" for ep in entry_points(group="multipole.bench_scenes"))

    class Entry:
        def __init__(self, name, provider):
            self.name, self.provider = name, provider

        def load(self):
            if self.provider is None:
                raise ImportError("fixture package not installed")
            return self.provider

    tagged = S.two_mass_oscillator(periods=1, name="tagged")
    untagged = S.two_mass_oscillator(periods=1, name="untagged", bench=False)
    data = S.two_mass_oscillator(periods=1, name="with_data")
    groups = {"multipole.bench_scenes": [Entry("mine", lambda: [("a.yaml", tagged), ("b.yaml", untagged)]),
                                         Entry("gone", None),
                                         Entry("files", lambda: [("sub/c.yaml", data, {"t.csv": "1, 2\n",
                                                                                      "d/u.csv": "3\n"})])]}
    monkeypatch.setattr(bench, "entry_points", lambda group: groups.get(group, []))
    scenes = bench.default_scenes()
    assert [sc.name for sc in scenes] == ["tagged", "with_data"]
    assert scenes[0].path == "mine:a.yaml"
    path = Path(scenes[1].path)                  # a scene with data files: loaded from the folder holding them
    assert path.parts[-3:] == ("files", "sub", "c.yaml") and path.read_text(encoding="utf-8") == data
    assert (path.parent / "t.csv").read_text(encoding="utf-8") == "1, 2\n"
    assert (path.parent / "d" / "u.csv").read_text(encoding="utf-8") == "3\n"


@pytest.mark.parametrize("name, files", [("../c.yaml", {"t.csv": ""}), ("c.yaml", {"../t.csv": ""}),
                                         ("c.yaml", {"/tmp/t.csv": ""})])
def test_a_provider_cannot_place_files_outside_the_scene_folder(monkeypatch, name, files):
    import multipole.bench as bench

    class Entry:
        name = "bad"

        def load(self):
            return lambda: [(name, S.two_mass_oscillator(periods=1), files)]
    monkeypatch.setattr(bench, "entry_points", lambda group: [Entry()])
    with pytest.raises(MultipoleError) as err:
        bench.default_scenes()
    assert err.value.code == "bad_bench_scene"


def test_the_belt_scenes_of_the_default_set_are_the_files_of_diagrams_belts():
    """The package's scene texts are diagrams/belts' files, and its tables are written by the code
    that wrote diagrams/belts' tables: the same numbers to the 17 digits written (libm may differ by
    an ulp or two on another machine; measured here: the same bytes)."""
    from multipole_models import belts
    from multipole_models.toothed_belt import table_texts
    for name, text in belts.SCENES.items():
        assert text == (ROOT / "diagrams" / "belts" / name).read_text(encoding="utf-8"), (
            f"diagrams/belts/{name} changed: copy its text into multipole_models/belts.py (the default bench set)")
    for name, text in table_texts().items():
        ours = _table_numbers(text)
        theirs = _table_numbers((ROOT / "diagrams" / "belts" / name).read_text(encoding="utf-8"))
        assert ours.shape == theirs.shape and ours.shape[0] > 1000, name
        np.testing.assert_allclose(ours, theirs, rtol=1e-14, atol=0, err_msg=name)


def _table_numbers(text: str) -> np.ndarray:
    """The (theta, r) rows of a contour table's text."""
    rows = [line.split(",") for line in text.splitlines() if line and line[0] not in "#t"]
    return np.array([[float(a), float(b)] for a, b in rows])


def _with_reference(ref: str) -> str:
    text = S.two_mass_oscillator(periods=1)
    head = text[:text.index("reference:")]
    return head + ref + "\n"


@pytest.mark.parametrize("ref, code", [
    ("reference: {kind: exact}", "bad_reference"),
    ("reference: {kind: closed_form, output: m1.v}", "bad_reference"),
    ("reference: {kind: tight, output: nowhere.v}", "bad_reference"),
    ("reference: {kind: tight, tolerance: 3}", "bad_reference"),
    ("reference: {kind: tight, no_hand_model: ' '}", "bad_reference"),
    ("reference: {kind: tight, no_hand_model: 3}", "bad_reference"),
    ("reference: {kind: tight, hand_model: two_mass_oscillator, no_hand_model: a reason}", "bad_reference"),
])
def test_bad_reference_mappings_are_refused(ref, code):
    with pytest.raises(MultipoleError) as err:
        reference_spec(loads(_with_reference(ref), "r.yaml"))
    assert err.value.code == code


def test_reference_formulas_go_through_the_expression_whitelist():
    sc = loads(_with_reference('reference: {kind: closed_form, output: m1.v, expression: "__import__(1)"}'), "r.yaml")
    with pytest.raises(NetlistError) as err:
        build_reference(sc, pipeline.model(sc))
    assert err.value.code == "unsafe_expression"


def test_closed_form_reference_and_error_measure():
    sc = loads(S.two_mass_oscillator(periods=2), "t.yaml")
    model = pipeline.model(sc)
    ref = build_reference(sc, model)
    assert ref.kind == "closed_form" and ref.error == 0.0 and ref.energy is not None
    res = simulate(model, ref.t_end, ref.dt_out, "RK45", 1e-4, 1e-7, progress=False)
    p = {k: float(v) for k, v in sc.network.params.items()}
    exact = S.linear_response(S._two_mass_matrix(p), S._two_mass_x0(p), [0, 1 / p["m1"], 0, 0], t=res.t)
    assert np.allclose(ref.at(res.t), exact, rtol=0, atol=1e-12)
    energy = ref.energy(res.t, res.outputs)
    E0 = 0.5 * p["m2"] * p["v2_0"] ** 2 + 0.5 * (p["k1"] + p["k2"]) * p["x1_0"] ** 2
    assert energy[0] == pytest.approx(E0, rel=1e-12)


def test_tight_reference_states_its_own_error():
    sc = loads(S.slack_rope(t_end=0.5), "r.yaml")
    ref = build_reference(sc, pipeline.model(sc))
    assert ref.kind == "tight" and 0 <= ref.error < 1e-9 and "1e-13" in ref.note


def test_explicit_stability_bound_of_a_real_stiff_eigenvalue():
    r = rk_stability_radius("RK45", np.pi)
    bound = explicit_stability_bound([-1e6, -1.0], "RK45", 2.0)
    assert bound["h_max"] == pytest.approx(r / 1e6)
    assert bound["steps"] == pytest.approx(2.0 * 1e6 / r, rel=1e-6, abs=1)
    assert bound["nfev"] == 6 * bound["steps"]
    assert explicit_stability_bound([1j, -1j], "RK45", 2.0)["nfev"] == 0       # undamped: accuracy, not stability


def test_bench_quick_smoke_writes_csv_figure_and_summary(tmp_path, capsys):
    scene_file = tmp_path / "tiny.yaml"
    scene_file.write_text(S.two_mass_oscillator(periods=1, name="two_mass_oscillator_tiny"), encoding="utf-8")
    out = tmp_path / "report"
    assert main(["bench", str(scene_file), "-o", str(out), "--quick", "--quiet"]) == 0
    assert "bench: 1 scene(s)" in capsys.readouterr().out
    rows = list(csv.DictReader(open(out / "bench.csv", encoding="utf-8")))
    numpy_rows = [r for r in rows if r["backend"] == "numpy"]
    assert {r["solver"] for r in numpy_rows} == {"RK45", "DOP853", "Radau", "BDF", "LSODA", "GL4", "auto"}
    assert {float(r["rtol"]) for r in numpy_rows} == {1e-3, 1e-6, 1e-9}
    ok = [r for r in numpy_rows if r["status"] == "ok"]
    assert len(ok) == len(numpy_rows)
    for r in ok:
        assert float(r["err_max"]) >= float(r["err_final"]) and int(r["nfev"]) > 0 and float(r["wall_s"]) > 0
    tight = [float(r["err_max"]) for r in ok if r["solver"] == "DOP853"]
    assert tight[-1] < tight[0]                               # tighter tolerance, smaller error
    hand_rows = [r for r in rows if r["backend"] == "scipy-hand"]
    assert {r["solver"] for r in hand_rows} == {"RK45", "DOP853", "Radau", "BDF", "LSODA"}
    # beyond the quick ladder only runs that extend it, tighter than its last rtol
    assert all(r["message"].startswith("ladder extended") for r in hand_rows if float(r["rtol"]) < 1e-9)
    assert all(r["status"] == "ok" for r in hand_rows)
    # same method, same tolerances, same equations: the hand-written run lands on the generated run's error
    for solver in ("RK45", "DOP853"):
        gen = [float(r["err_max"]) for r in numpy_rows if r["solver"] == solver]
        own = [float(r["err_max"]) for r in hand_rows if r["solver"] == solver and float(r["rtol"]) >= 1e-9]
        assert np.allclose(own, gen, rtol=1e-6)
    equal = list(csv.DictReader(open(out / "equal_error.csv", encoding="utf-8")))
    compiled = {r["backend"] for r in rows} - {"numpy", "scipy-hand"}
    assert {r["backend"] for r in equal} == compiled and len(equal) == 3 * len(compiled)
    for r in equal:
        hand = [h for h in hand_rows if h["status"] == "ok" and float(h["err_max"]) <= float(r["level"])]
        if hand:                     # the fastest hand-written run at that error, and the ratio to the backend's
            assert float(r["hand_s"]) == pytest.approx(min(float(h["wall_s"]) for h in hand), rel=1e-5)
        if r["hand_solver"] and r["backend_solver"]:      # both re-timed interleaved: a ratio within its spread
            assert int(r["rounds"]) >= 3 and float(r["ratio_lo"]) <= float(r["ratio"]) <= float(r["ratio_hi"])
            met = r["verdict"] == "met"
            assert met == (float(r["ratio_lo"]) >= SPEEDUP_TARGET) and float(r["hand_cpu_s"]) > 0 < float(r["backend_cpu_s"])
    side = list(csv.DictReader(open(out / "side_by_side.csv", encoding="utf-8")))
    assert len(side) == 1 and float(side[0]["rhs_mismatch"]) < 1e-12 and float(side[0]["rhs_ratio"]) > 0
    assert (out / "bench_two_mass_oscillator_tiny.png").stat().st_size > 10_000
    summary = (out / "summary.md").read_text(encoding="utf-8")
    assert "## two_mass_oscillator_tiny" in summary and "Pick **" in summary and "closed form" in summary


def test_naive_run_over_budget_gives_a_lower_bound_of_the_speedup():
    from multipole.bench import _Bar, bench_scene
    sc = loads(S.stiff_drive_train(t_end=0.5), "s.yaml")
    rep = bench_scene(sc, ["auto"], [1e-6], 1, ["numpy"], 4e5, _Bar(1, False), naive_budget=1e3)
    side = rep.side
    assert side["naive_status"].startswith("skipped")
    p = {k: float(v) for k, v in sc.network.params.items()}
    bound = explicit_stability_bound(np.linalg.eigvals(S._stiff_matrix(p)), "RK45", 0.5)
    assert side["naive_min_nfev"] == bound["nfev"] > 1e3
    assert side["naive_lower_s"] == pytest.approx(bound["nfev"] * side["rhs_hand_us"] * 1e-6)
    auto = [r for r in rep.runs if r.solver == "auto" and r.backend == "numpy"]
    assert side["naive_speedup_min"] == pytest.approx(side["naive_lower_s"] / auto[0].wall_s)
    hand = [r for r in rep.runs if r.backend == "scipy-hand"]
    assert {r.status for r in hand if r.solver in ("RK45", "DOP853")} == {"skipped"}      # stability bound
    assert all(r.status == "ok" and r.err_max < 1e-4 for r in hand if r.solver in ("Radau", "BDF", "LSODA"))


def test_equal_error_takes_the_fastest_run_of_each_side_at_each_level():
    from multipole.bench import SPEEDUP_TARGET, Reference, Run, SceneReport, equal_error
    rep = SceneReport("s", "s.yaml", Reference("tight", "y", 1.0, 0.1, 1e-8, "tight"))
    # (backend, solver, err_max, wall_s): the hand-written side reaches 1e-3 at best in 10 ms (LSODA), 1e-6 in
    # 60 ms (Radau; BDF is faster but not accurate enough); the compiled side 1e-3 in 0.1 ms, 1e-6 in 4 ms
    for backend, solver, err, wall in (("scipy-hand", "LSODA", 5e-4, 0.010), ("scipy-hand", "BDF", 2e-6, 0.020),
                                       ("scipy-hand", "Radau", 5e-7, 0.060), ("scipy-hand", "RK45", 5e-4, 0.030),
                                       ("numba", "RK45", 8e-4, 0.0001), ("numba", "Radau", 9e-7, 0.004),
                                       ("numba", "Radau", 1e-12, 0.009)):
        rep.runs.append(Run("s", backend, solver, 1e-3, 1e-6, err_max=err, wall_s=wall, chosen=solver))
    rep.runs.append(Run("s", "numba", "RK45", 1e-3, 1e-6, status="failed", err_max=1e-13, wall_s=1e-6))
    rows = {r["level"]: r for r in equal_error(rep, "numba", levels=(1e-3, 1e-6, 1e-7, 1e-9))}
    assert rows[1e-3]["hand_solver"] == "LSODA" and rows[1e-3]["ratio"] == pytest.approx(0.010 / 0.0001)
    assert SPEEDUP_TARGET < 100 and rows[1e-3]["verdict"] == "met"
    assert rows[1e-6]["hand_solver"] == "Radau" and rows[1e-6]["ratio"] == pytest.approx(0.060 / 0.004)
    assert rows[1e-6]["verdict"] == "not met"                         # 15 < 50
    assert rows[1e-7]["verdict"].startswith("unreached by the hand-written model")  # the compiled side did (1e-12)
    assert rows[1e-9]["verdict"].startswith("not measurable")       # within 3x the reference's own error
    rep.runs = [r for r in rep.runs if r.err_max > 1e-11]
    rows = {r["level"]: r for r in equal_error(rep, "numba", levels=(1e-7,))}
    assert rows[1e-7]["verdict"].startswith("not compared: unreached by numba")   # neither side reached it


# -- the bench's timing and ladder, with fake contenders (structure, never timings) --------------------

def test_contenders_are_timed_interleaved_after_one_warm_up_each(monkeypatch):
    import multipole.bench as bench
    order = []
    timings = bench.interleaved({"A": lambda: order.append("A"), "B": lambda: order.append("B")}, rounds=4)
    assert order == ["A", "B"] + ["A", "B"] * 4                       # warm-up, then A B A B ...
    assert all(len(t.cpu) == len(t.wall) == 4 for t in timings.values())
    # the CPU clock is the process's, the wall clock perf_counter's: fake both and read them back
    clocks = {"cpu": iter(range(0, 100, 1)), "wall": iter(range(0, 1000, 10))}
    monkeypatch.setattr(bench.time, "process_time", lambda: next(clocks["cpu"]))
    monkeypatch.setattr(bench.time, "perf_counter", lambda: next(clocks["wall"]))
    timings = bench.interleaved({"A": lambda: None}, rounds=2)
    assert timings["A"].cpu == [1, 1] and timings["A"].wall == [10, 10]


@pytest.mark.parametrize("hand_cpu, comp_cpu, verdict", [
    ([60, 70, 80], [1, 1, 1], "met"),                        # every round >= 50
    ([30, 40, 45], [1, 1, 1], "not met"),                    # every round < 50
    ([40, 55, 70], [1, 1, 1], "within noise"),               # median 55 >= 50, but the spread straddles it
])
def test_a_verdict_is_met_only_beyond_the_measured_spread(hand_cpu, comp_cpu, verdict):
    from multipole.bench import Timing, ratio_verdict
    row = ratio_verdict(Timing(hand_cpu, hand_cpu), Timing(comp_cpu, comp_cpu), target=50.0)
    assert row["verdict"].startswith(verdict)
    assert row["ratio"] == float(np.median(hand_cpu)) and (row["ratio_lo"], row["ratio_hi"]) == (hand_cpu[0], hand_cpu[-1])


class _FakeResult:
    """What the bench reads from a run: a constant offset ``err`` from the reference y = 1."""

    def __init__(self, err, solver):
        self.t = np.linspace(0.0, 1.0, 11)
        self.outputs = {"y": np.ones(11) + err}
        self.solver, self.events = solver, []
        self.stats = {"nfev": 10, "steps": 5}

    def __getitem__(self, name):
        return self.outputs[name]


def _fake_report(errors):
    """A scene report whose two contenders ran rtol 1e-3 ... 1e-6 with error ``errors[side](rtol)``."""
    from multipole.bench import HAND, Reference, Run, SceneReport
    rep = SceneReport("s", "s.yaml", Reference("closed_form", "y", 1.0, 0.1, 0.0, "exact",
                                               formula=lambda t, _: np.ones_like(t)))
    for side in (HAND, "numba"):
        for rtol in (1e-3, 1e-4, 1e-5, 1e-6):
            rep.runs.append(Run("s", side, "DOP853", rtol, rtol, err_max=errors[side](rtol), wall_s=1e-3, chosen="DOP853"))
    return rep


def test_the_ladder_is_extended_until_each_contender_reaches_each_level_or_it_is_marked_unreached():
    from multipole.bench import HAND, extend_ladder, equal_error
    # the hand-written side's error is 50 rtol (reaches 1e-6 at rtol 1e-8, 1e-9 at rtol 1e-11); the compiled
    # side's error stalls at 1e-8 below rtol 1e-8 (a method's floor): it never reaches 1e-9
    errors = {HAND: lambda rtol: 50 * rtol, "numba": lambda rtol: max(rtol, 1e-8)}
    rep = _fake_report(errors)
    asked = {HAND: [], "numba": []}

    def attempt_of(side):
        def attempt(solver, rtol, atol):
            asked[side].append(rtol)
            return _FakeResult(errors[side](rtol), solver), [1e-3]
        return attempt
    for side in (HAND, "numba"):
        extend_ladder(rep, side, (1e-3, 1e-6, 1e-9), attempt_of(side), ratio=1.0)
    assert asked[HAND] == pytest.approx([1e-7, 1e-8, 1e-9, 1e-10, 1e-11])   # down to the first run reaching 1e-9
    assert asked["numba"] == pytest.approx([1e-7, 1e-8, 1e-9])              # stops where the error stalls
    extended = [r for r in rep.runs if r.message == "ladder extended"]
    assert len(extended) == 8 and all(r.status == "ok" for r in extended)
    rows = {r["level"]: r for r in equal_error(rep, "numba", levels=(1e-3, 1e-6, 1e-9))}
    assert rows[1e-9]["verdict"] == "not met: unreached by numba (down to rtol 1e-09)"
    assert rows[1e-9]["hand_rtol"] == pytest.approx(1e-11)
    assert rows[1e-6]["verdict"] in ("met", "not met")


def test_the_ladder_stops_at_its_floor():
    from multipole.bench import HAND, extend_ladder
    errors = {HAND: lambda rtol: 1e3 * rtol, "numba": lambda rtol: rtol}
    rep = _fake_report(errors)
    asked = []

    def attempt(solver, rtol, atol):
        asked.append(rtol)
        return _FakeResult(errors[HAND](rtol), solver), [1e-3]
    extend_ladder(rep, HAND, (1e-9,), attempt, ratio=1.0, floor=1e-10)
    assert asked == pytest.approx([1e-7, 1e-8, 1e-9, 1e-10])               # 1e3 * 1e-10 = 1e-7 > 1e-9: unreached


def test_equal_error_retimes_the_two_chosen_runs_interleaved():
    from multipole.bench import HAND, equal_error
    rep = _fake_report({HAND: lambda rtol: rtol, "numba": lambda rtol: rtol})
    calls = []

    def call_of(side):
        def call(solver, rtol, atol):
            calls.append((side, rtol))
            return _FakeResult(0.0, solver)
        return call
    rep.calls = {HAND: call_of(HAND), "numba": call_of("numba")}
    row = equal_error(rep, "numba", levels=(1e-5,), rounds=3)[0]
    # the fastest runs reaching 1e-5 (equal sweep times: the first found, rtol 1e-5), warm-up + 3 rounds each
    assert calls == [(HAND, 1e-5), ("numba", 1e-5)] * 4
    assert row["rounds"] == 3 and row["ratio_lo"] <= row["ratio"] <= row["ratio_hi"]


def test_every_solver_that_misses_a_level_gets_its_ladder_extended_unless_already_slower():
    """The issue's case: hand-written LSODA just misses 1e-9 at the ladder's end while Radau reaches it
    slowly; LSODA's ladder goes on (and wins), BDF's does not (already slower than Radau), nor RK45's
    (its tightest rtol failed)."""
    from multipole.bench import HAND, Reference, Run, SceneReport, extend_ladder, fastest
    rep = SceneReport("s", "s.yaml", Reference("closed_form", "y", 1.0, 0.1, 0.0, "exact",
                                               formula=lambda t, _: np.ones_like(t)))
    err = {"Radau": lambda rtol: 0.2 * rtol, "LSODA": lambda rtol: 5 * rtol, "BDF": lambda rtol: 5 * rtol,
           "RK45": lambda rtol: 5 * rtol}
    wall = {"Radau": 0.050, "LSODA": 0.005, "BDF": 0.100, "RK45": 0.001}
    for solver in err:
        for rtol in (1e-7, 1e-8, 1e-9):
            rep.runs.append(Run("s", HAND, solver, rtol, rtol, err_max=err[solver](rtol), wall_s=wall[solver]))
    rep.runs[-1].status = "failed"                                     # RK45 at rtol 1e-9
    asked = []

    def attempt(solver, rtol, atol):
        asked.append((solver, rtol))
        return _FakeResult(err[solver](rtol), solver), [wall[solver]]
    extend_ladder(rep, HAND, (1e-9,), attempt, ratio=1.0)
    assert [(s, pytest.approx(r)) for s, r in asked] == [("LSODA", 1e-10)]
    assert fastest(rep, 1e-9, HAND).solver == "LSODA"
