"""Weber's planetary gear (elements/planetary.py) against the Willis relations (W8, eqs. (43)–(50)).

Port efforts are torques acting ON the gear (sun = shaft I, ring = shaft II, carrier = s), flows
angular velocities.  Expected values: Willis (ω_I − ω_s)/(ω_II − ω_s) = i0, (−M_II) = i0·M_I,
(−M_s) = (1 − i0)·M_I, M_I + M_II + M_s = 0, and Lagrange's effective inertia for the planet spin.
"""
from pathlib import Path

import numpy as np
import pytest

from helpers import check, codes, run
from multipole import pipeline
from multipole.cli import main
from multipole.netlist import load

WEBER = Path(__file__).resolve().parents[1] / "diagrams" / "weber"
STEPPED = (0.03, 0.015, 0.02, 0.025)                 # r1 (sun), r2 (planet p1), r3 (planet p2), r4


def _check_willis(res, i0):
    w_I, w_II, w_s = (res[f"pg.{p}.f"][-1] for p in ("sun", "ring", "carrier"))
    M_I, M_II, M_s = (res[f"pg.{p}.e"][-1] for p in ("sun", "ring", "carrier"))
    assert (w_I - w_s) / (w_II - w_s) == pytest.approx(i0, rel=1e-12)          # (46)
    assert -M_II == pytest.approx(i0 * M_I, rel=1e-12)                          # (49)
    assert -M_s == pytest.approx((1 - i0) * M_I, rel=1e-12)                     # (48)
    assert abs(M_I + M_II + M_s) <= 1e-12 * abs(M_I)                            # (50)
    assert abs(M_I * w_I + M_II * w_II + M_s * w_s) <= 1e-12 * abs(M_I * w_I)   # lossless
    return M_I, w_I, w_s


@pytest.mark.parametrize("w_sun, w_carrier, M_ring", [(100.0, 20.0, 12.0), (-35.0, 50.0, -4.0), (0.0, 10.0, 1.0)])
def test_simple_planetary_follows_willis(w_sun, w_carrier, M_ring):
    sc = load(WEBER / "planetary_willis.yaml", {"w_sun": str(w_sun), "w_carrier": str(w_carrier),
                                                 "M_ring": str(M_ring)})
    res = pipeline.run(sc, progress=False)
    i0 = -72 / 24                                   # internal ring: i0 = -z_ring/z_sun
    assert res["pg.i0"][-1] == pytest.approx(i0)
    M_I, w_I, w_s = _check_willis(res, i0)
    # Bild 33: rolling power (through the meshes) + coupling power (carrier rotation) = P_I
    assert res["pg.rolling_power"][-1] + res["pg.coupling_power"][-1] == pytest.approx(M_I * w_I, rel=1e-12,
                                                                                       abs=1e-12)
    assert res["pg.coupling_power"][-1] == pytest.approx(M_I * w_s, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("internal", [False, True])
def test_stepped_planets_follow_willis(internal):
    r1, r2, r3, r4 = STEPPED if not internal else (0.03, 0.015, 0.01, 0.055)
    i0 = (-r2 / r1) * ((1 if internal else -1) * r4 / r3)               # (47), ring gear: +r4/r3
    res = run(f"""
    elements:
      pg:      {{type: planetary, r1: {r1}, r2: {r2}, r3: {r3}, r4: {r4}, internal: {str(internal).lower()}}}
      ring:    {{type: speed_source, value: 7.0}}
      carrier: {{type: speed_source, value: -3.0}}
      sun:     {{type: torque_source, value: 2.5}}
    connections:
      - [sun.p, pg.sun]
      - [carrier.p, pg.carrier]
      - [ring.p, pg.ring]
    outputs: [pg.sun.f, pg.ring.f, pg.carrier.f, pg.sun.e, pg.ring.e, pg.carrier.e, pg.i0]
    simulate: {{t_end: 0.01, dt_out: 0.01}}
    """)
    assert res["pg.i0"][-1] == pytest.approx(i0)
    _check_willis(res, i0)


def test_two_speeds_and_one_torque_are_accepted_three_speeds_or_two_torques_are_not(capsys):
    assert main(["check", str(WEBER / "planetary_willis.yaml")]) == 0
    assert main(["check", str(WEBER / "planetary_three_speeds.yaml")]) == 1
    out = capsys.readouterr().out
    assert "over-determination" in out
    three = pipeline.check(load(WEBER / "planetary_three_speeds.yaml"))
    assert {"source_conflict"} <= {d.code for d in three.errors}
    conflict = next(d for d in three.errors if d.code == "source_conflict")
    assert conflict.message.startswith("carrier, ring and sun all impose the angular velocity")
    two_torques = """
    elements:
      pg:      {type: planetary, z_sun: 24, z_ring: 72}
      sun:     {type: torque_source, value: 1}
      carrier: {type: speed_source, value: 2}
      ring:    {type: torque_source, value: 3}
    connections:
      - [sun.p, pg.sun]
      - [carrier.p, pg.carrier]
      - [ring.p, pg.ring]
    """
    assert not check(two_torques).ok and "source_conflict" in codes(two_torques)


def test_planet_spin_inertia_gives_lagranges_effective_inertia():
    """Rigid meshes, ring held, torque M on the sun: ω_s = ω_I/(1 − i0), planet absolute speed
    ω_p = ω_s·(1 + r4/r3), so J_eff = J_I + (J_s + J_p·(1 + r4/r3)²)/(1 − i0)² and ω_I = M·t/J_eff."""
    r1, r2, r3, r4 = STEPPED
    M, J_I, J_s, J_p = 0.4, 1e-4, 5e-3, 2e-4
    i0 = (-r2 / r1) * (-r4 / r3)
    res = run(f"""
    elements:
      motor:   {{type: torque_source, value: {M}}}
      sun_in:  {{type: inertia, J: {J_I}}}
      pg:      {{type: planetary, r1: {r1}, r2: {r2}, r3: {r3}, r4: {r4}, J_p: {J_p}}}
      cage:    {{type: inertia, J: {J_s}}}
      ring:    {{type: speed_source, value: 0}}
    connections:
      - [motor.p, sun_in.a]
      - [sun_in.b, pg.sun]
      - [pg.carrier, cage.a]
      - [pg.ring, ring.p]
    outputs: [sun_in.omega, cage.omega]
    simulate: {{t_end: 0.5, dt_out: 0.01, rtol: 1.0e-10, atol: 1.0e-12}}
    """)
    J_eff = J_I + (J_s + J_p * (1 + r4 / r3) ** 2) / (1 - i0) ** 2
    assert np.allclose(res["sun_in.omega"], M * res.t / J_eff, rtol=1e-9, atol=1e-12)
    assert np.allclose(res["cage.omega"], res["sun_in.omega"] / (1 - i0), rtol=1e-9, atol=1e-12)


def test_elastic_planetary_settles_to_the_rigid_torque_split():
    """Elastic meshes, ring held, sun torque M, carrier load d: at steady state
    ω_s = (1 − i0)·M/d (power balance), ω_I = (1 − i0)·ω_s, F12 = M/r1, F34 = −(r2/r3)·F12."""
    r1, r2, r3, r4 = STEPPED
    M, d = 2.0, 0.5
    i0 = (-r2 / r1) * (-r4 / r3)
    res = run(f"""
    elements:
      motor:   {{type: torque_source, value: {M}}}
      sun_in:  {{type: inertia, J: 1.0e-4}}
      pg:      {{type: planetary, r1: {r1}, r2: {r2}, r3: {r3}, r4: {r4}, c: 1.0e8, d: 500, J_p: 2.0e-5}}
      cage:    {{type: inertia, J: 5.0e-3}}
      load:    {{type: damper, d: {d}}}
      housing: {{type: ground}}
      ring:    {{type: speed_source, value: 0}}
    connections:
      - [motor.p, sun_in.a]
      - [sun_in.b, pg.sun]
      - [pg.carrier, cage.a]
      - [cage.b, load.a]
      - [load.b, housing.p]
      - [pg.ring, ring.p]
    outputs: [sun_in.omega, cage.omega, pg.mesh12.force, pg.mesh34.force]
    simulate: {{t_end: 1.0, dt_out: 0.01, rtol: 1.0e-9, atol: 1.0e-12}}
    """)
    w_s = (1 - i0) * M / d
    assert res["cage.omega"][-1] == pytest.approx(w_s, rel=1e-6)
    assert res["sun_in.omega"][-1] == pytest.approx((1 - i0) * w_s, rel=1e-6)
    assert res["pg.mesh12.force"][-1] == pytest.approx(M / r1, rel=1e-6)
    assert res["pg.mesh34.force"][-1] == pytest.approx(-(r2 / r3) * M / r1, rel=1e-6)


def test_planetary_parameters_are_checked():
    from multipole.errors import NetlistError
    for bad, code in (("{type: planetary, z_sun: 24}", "conflicting_parameters"),
                      ("{type: planetary, z_sun: 24, z_ring: 72, r1: 0.1}", "conflicting_parameters"),
                      ("{type: planetary, r1: 0.03, r2: 0.015}", "missing_parameter"),
                      ("{type: planetary, z_sun: 30, z_ring: 30}", "bad_value")):
        with pytest.raises(NetlistError) as err:
            check(f"""
            elements:
              pg: {bad}
            connections: []
            """)
        assert err.value.code == code, bad
