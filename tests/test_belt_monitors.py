"""Belt and rope monitors (issue 13): run-time (``multipole.Monitor`` declared by band_roll and drum)
and static (the checks registered by elements/belt_checks.py).  Each has a netlist that triggers
it and one that does not; the expected times and values come from the kinematics and statics of
the scene written here."""
import math
import re
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from multipole import MultipoleError, Network, Sf, analyse, assemble, compile_model, flatten, pipeline, simulate
from multipole.netlist import load
from tests.helpers import scene

BELTS = Path(__file__).resolve().parents[1] / "diagrams" / "belts"
DRIVE = (BELTS / "belt_drive.yaml").read_text()


def found(text, code, overrides=None):
    return [d for d in pipeline.check(scene(text, overrides)).diagnostics if d.code == code]


def printed(message: str, label: str) -> float:
    """The number a diagnostic's message prints right after ``label`` (compared with a tolerance of
    its printed digits, never as text)."""
    match = re.search(re.escape(label) + r" ([-+]?[0-9.]+(?:e[-+]?[0-9]+)?)", message)
    assert match, f"no number after {label!r} in {message!r}"
    return float(match.group(1))


# -- drum paying out past its anchor (run-time, stops the run) ------------------------------------

WINCH = """
name: winch_lowering
# a drum lowers a hanging load at v: it pays rope out at v, the wound-out length is v t
parameters: {v: 0.5, r: 0.1, m: 10.0, g: 9.81, EA: 2.0e4, stored: 0.2}
elements:
  motor: {type: speed_source, value: v/r}
  drum: {type: drum, r: r, J: 0.01, stored: stored}
  rope: {type: band, EA: EA, cd: 100.0, l: 1.0, l0: 1.0/(1 + m*g/EA), dir: -1}
  load: {type: mass, m: m, v0: -v}
  weight: {type: force_source, value: -m*g}
connections:
  - [motor.p, drum.drive]
  - [drum.e1, rope.e1]
  - [rope.p2, load.a, weight.p]
outputs: [rope.F, rope.lr1, load.v]
simulate: {t_end: 1.0, rtol: 1e-10}
"""


def test_drum_paying_out_past_its_stored_rope_stops_the_run_at_that_time():
    """0.2 m stored, paid out at 0.5 m/s: the rope end reaches the anchor at t = 0.4 s."""
    with pytest.raises(MultipoleError) as exc:
        pipeline.run(scene(WINCH), progress=False)
    assert exc.value.code == "drum_paid_out"
    assert "drum" in str(exc.value) and "anchor" in str(exc.value)
    t = float(str(exc.value).split("at t = ")[1].split(" s")[0])
    assert t == pytest.approx(0.2 / 0.5, abs=1e-6)          # the time is printed with 6 digits


def test_drum_with_rope_to_spare_runs_to_the_end():
    res = pipeline.run(scene(WINCH, {"stored": 1.0}), progress=False)
    assert res.t[-1] == pytest.approx(1.0) and res.monitors == []
    assert res.outputs["rope.lr1"][-1] == pytest.approx(0.5 * 1.0, rel=1e-9)   # 0.5 m paid out of 1 m


# -- capstan limit on a no-slip roll (run-time, reported) -----------------------------------------

def _drive_with_mu_c(mu_c: float) -> str:
    text = DRIVE.replace("p1: {type: band_roll, r: 0.05, J: 1.0e-3}",
                         f"p1: {{type: band_roll, r: 0.05, J: 1.0e-3, mu_c: {mu_c}}}")
    assert text != DRIVE
    return text


def test_capstan_limit_is_reported_when_the_tension_ratio_reaches_exp_mu_wrap():
    """Both spans pretensioned to 200 N; the load torque grows at 2.5 N*m/s, so F_t - F_s grows and
    the ratio F_t/F_s reaches e^(mu_c pi) = 1.3691 (mu_c = 0.1, wrap pi) once: reported at that
    time on p1, the run goes on.  Quasi-statically F_t + F_s = 2 EA d0/l0 = 400.8 N (the stretches
    add to 2 d0 = 2 (l - l0); the free lengths differ from l0 by 1e-4 relative), so
    T = r2 (F_t - F_s) = r2 400.8 (e - 1)/(e + 1) = 6.245 N*m at t = 2.4978 s (measured 2.49792:
    the damper and the pulleys' inertia)."""
    text = _drive_with_mu_c(0.1)
    sc = scene(text, {"rate": 2.5, "cd": 4.0})
    res = pipeline.run(sc, t_end=4.0, progress=False)
    hits = [m for m in res.monitors if m[2] == "capstan_limit"]
    assert len(hits) == 1 and hits[0][1] == "p1", res.monitors
    e = math.exp(0.1 * math.pi)
    t_m = hits[0][0]
    l0 = 0.8 - 200.0 * 0.8 / 1.0e5
    assert t_m == pytest.approx(0.1 * 2 * 1.0e5 * (0.8 - l0) / l0 * (e - 1) / (e + 1) / 2.5, rel=2e-4)
    # the tensions at the reported time: the ratio is the limit (run again to end exactly there)
    at = pipeline.run(scene(text, {"rate": 2.5, "cd": 4.0}), t_end=t_m, progress=False)
    assert at.outputs["tight.F"][-1] / at.outputs["slack.F"][-1] == pytest.approx(e, rel=1e-6)
    assert res.t[-1] == pytest.approx(4.0)


def test_capstan_limit_is_quiet_below_the_limit():
    """mu_c = 0.3: e^(0.3 pi) = 2.57; by t = 4 s the ratio is (200 + 50)/(200 - 50) = 1.67."""
    res = pipeline.run(scene(_drive_with_mu_c(0.3), {"rate": 2.5, "cd": 4.0}), t_end=4.0, progress=False)
    assert res.monitors == []
    ratio = res.outputs["tight.F"][-1] / res.outputs["slack.F"][-1]
    assert 1.6 < ratio < math.exp(0.3 * math.pi)


def test_rolls_without_mu_c_declare_no_capstan_monitor():
    flat = flatten(scene(DRIVE).network)
    assert flat.monitors == []
    flat = flatten(scene(_drive_with_mu_c(0.1)).network)
    assert sorted((m.code, owner) for _e, m, owner in flat.monitors) == [("capstan_limit", "p1")] * 2


# -- band lifting off (wrap -> 0) -----------------------------------------------------------------

def test_band_lifting_off_a_roll_whose_wrap_shrinks_is_reported():
    """A roll whose wrap angle is an expression of its motion (here pi/2 - phi, as for a roll whose
    spans swing with it; the 1-D netlist roll has a constant wrap) turning at 2 rad/s: the wrap
    reaches 0 at t = pi/4 s, reported there; the run goes on."""
    from elements.belt import _roll
    roll = _roll("band_roll", 2, 0.05, 0.01, 0.0, 0.0, 1, 0, 0.004, sp.pi / 2 - sp.Symbol("phi"))
    net = Network("scene", {"roll": roll, "motor": Sf(2.0, "rotational")}, [["roll.drive", "motor.p"]])
    res = simulate(compile_model(assemble(analyse(flatten(net))), ["roll.phi"]), 1.0, 0.01, rtol=1e-10,
                   atol=1e-12, progress=False)
    assert [(m[1], m[2]) for m in res.monitors] == [("roll", "band_lifts_off")]
    assert res.monitors[0][0] == pytest.approx(math.pi / 4, abs=1e-9)
    assert res.t[-1] == pytest.approx(1.0)


def test_a_constant_wrap_declares_no_lift_off_monitor():
    """The netlist roll's wrap is a parameter (> 0, checked at load time): nothing to watch."""
    flat = flatten(load(BELTS / "pulley_block.yaml").network)
    assert [m.code for _e, m, _o in flat.monitors] == []


# -- belt loop and its length (static) ------------------------------------------------------------

def test_belt_loop_reports_the_belt_length_of_the_two_pulley_drive():
    """Two spans of free length l0 = l (1 - F0/EA) and half wraps on r1 = 0.05 m, r2 = 0.1 m: belt
    length 2 l0 + pi (r1 + r2) = 2.06804 m; mean pretension EA (2l - 2l0)/(2 l0) = 200.4 N."""
    [d] = found(DRIVE, "belt_loop")
    assert set(d.elements) == {"p1", "p2", "tight", "slack"}
    l0 = 0.8 - 200.0 * 0.8 / 1.0e5
    assert printed(d.message, "belt length") == pytest.approx(2 * l0 + math.pi * 0.15, rel=5e-6)   # 6 digits
    assert printed(d.message, "mean pretension") == pytest.approx(1e5 * (0.8 - l0) / l0, rel=5e-4)   # 4 digits
    assert found(DRIVE, "belt_loop_slack") == []


def test_an_open_rope_is_no_belt_loop():
    assert found((BELTS / "pulley_block.yaml").read_text(), "belt_loop") == []


def test_belt_loop_slack_when_the_free_lengths_do_not_close_under_tension():
    """F0 = -10 N: l0 = l (1 + 1e-4) > l: the loop's free lengths exceed its span lengths."""
    [d] = found(DRIVE, "belt_loop_slack", {"F0": -10.0})
    assert printed(d.message, "free lengths add to") == pytest.approx(2 * 0.8 * (1 + 10.0 / 1.0e5), rel=5e-6)
    assert printed(d.message, "span lengths") == pytest.approx(2 * 0.8, rel=5e-6)
    assert d.severity == "warning"


def test_belt_length_is_invariant_over_a_run():
    """The rolls hand each wound length from one span to the next: the free lengths of the loop add
    to 2 l0 at every output time (to rounding), while each changes by a millimetre as the load grows."""
    res = pipeline.run(scene(DRIVE, {"rate": 25.0}), t_end=1.0, progress=False, outputs=["tight.free", "slack.free"])
    total = res.outputs["tight.free"] + res.outputs["slack.free"]
    np.testing.assert_allclose(total, 2 * (0.8 - 200.0 * 0.8 / 1.0e5), rtol=1e-12)
    assert np.ptp(res.outputs["tight.free"]) > 5e-4


# -- capstan limit at rest (static) ---------------------------------------------------------------

UNEQUAL = DRIVE.replace("tight: {type: band, EA: EA, cd: cd, l: l, l0: l - F0*l/EA}",
                        "tight: {type: band, EA: EA, cd: cd, l: l, l0: l - 2*F0*l/EA}")
assert UNEQUAL != DRIVE


@pytest.mark.parametrize("mu_c,warned", [(0.1, True), (0.3, False)])
def test_capstan_limit_at_rest(mu_c, warned):
    """Pretensions about 400 N (tight) and 200 N (slack): ratio 2.004 against e^(mu_c pi) = 1.37 (0.1:
    warned) and 2.57 (0.3: not)."""
    text = UNEQUAL.replace("p1: {type: band_roll, r: 0.05, J: 1.0e-3}",
                           f"p1: {{type: band_roll, r: 0.05, J: 1.0e-3, mu_c: {mu_c}}}")
    assert "mu_c" in text
    ds = found(text, "capstan_at_rest")
    assert bool(ds) == warned
    if warned:
        assert ds[0].elements == ["p1"]
        # a span of free length l0 = l (1 - k F0/EA) stretched to l: tension k F0 l/l0 (EA = 1e5 N, F0 = 200 N)
        tight, slack = (k * 200.0 / (1 - k * 200.0 / 1.0e5) for k in (2, 1))
        assert printed(ds[0].message, "ratio") == pytest.approx(tight / slack, rel=5e-4)            # 4 digits
        assert printed(ds[0].message, "e^(mu_c*wrap) =") == pytest.approx(math.exp(0.1 * math.pi), rel=5e-4)


def belt_triggers() -> dict:
    """The static belt checks' triggering netlists, for tests/test_diagnostics_text.py."""
    text = UNEQUAL.replace("p1: {type: band_roll, r: 0.05, J: 1.0e-3}",
                           "p1: {type: band_roll, r: 0.05, J: 1.0e-3, mu_c: 0.1}")
    return {"belt_loop": (lambda: scene(DRIVE), ["p1 -> slack -> p2 -> tight", "belt length"]),
            "belt_loop_slack": (lambda: scene(DRIVE, {"F0": -10.0}), ["too long", "l0"]),
            "capstan_at_rest": (lambda: scene(text), ["p1", "capstan limit"])}
