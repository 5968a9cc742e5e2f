"""The belt scenes of the default bench set: the toothed belt with two non-circular wheels (Ebert
7.3.2) and the belt-driven compressor (Ebert 8.2), offered to ``multipole bench`` through the
``belts`` entry of the ``multipole.bench_scenes`` entry point group.

A netlist reads its data files from its own folder, and an installed package has no ``diagrams/``
to read from, so :func:`bench_scenes` gives each scene as ``(file name, YAML text, {data file name:
text})``: the bench writes the files into a private temporary folder and loads the scene from
there.  The texts are those of ``diagrams/belts/toothed_belt.yaml`` and
``diagrams/belts/compressor.yaml`` (``tests/test_bench_scenes.py`` holds them equal); the toothed
belt's two contour tables are written by the same code that writes ``diagrams/belts``' tables
(:func:`multipole_models.toothed_belt.table_texts`, run by ``diagrams/belts/toothed_belt_design.py``).
The compressor has no hand-written model and says why in its ``reference: {no_hand_model: ...}``.
"""
from __future__ import annotations

__all__ = ["TOOTHED_BELT", "COMPRESSOR", "SCENES", "bench_scenes"]

#: diagrams/belts/toothed_belt.yaml
TOOTHED_BELT = """\
name: toothed_belt
# toothed belt with two non-circular wheels (Ebert 7.3.2): centre distance 800 mm, mean ratio 2:1,
# i_max/i_min = 1.5, driven at the small wheel at 360 deg/s over 720 deg.  1-D model: the spans keep
# their direction (parallel, horizontal); the pitch curves (tables made by toothed_belt_design.py)
# are centrally symmetric, so both spans see the same lever arms and the belt length in the model
# is invariant (docs/belts.md, "Toothed belt with two non-circular wheels").
# The spans start at the static tensions F0 +- T/(2 p2) (p2 = 0.1664 m: wheel 2's lever arm at phi = 0).
parameters: {w: 6.283185307179586, EA: 1.0e5, cd: 50.0, l: 0.8, F0: 100.0, T: 5.0, dF: T/(2*0.1664)}
elements:
  motor: {type: speed_source, value: w}
  wheel1: {type: curve_roll, contour: toothed_belt_wheel1.csv, J: 2.0e-3}
  wheel2: {type: curve_roll, contour: toothed_belt_wheel2.csv, J: 0.05, omega0: w/(2/sqrt(1 - 0.2**2)*1.2)}
  top: {type: band, EA: EA, cd: cd, l: l, l0: l/(1 + (F0 + dF)/EA), gamma: 0}
  bottom: {type: band, EA: EA, cd: cd, l: l, l0: l/(1 + (F0 - dF)/EA), gamma: pi}
  load: {type: torque_source, value: -T}
connections:
  - [motor.p, wheel1.drive]
  - [wheel1.e1, bottom.e2]
  - [bottom.e1, wheel2.e2]
  - [wheel2.e1, top.e2]
  - [top.e1, wheel1.e2]
  - [load.p, wheel2.drive]
outputs: [wheel1.phi, wheel1.omega, wheel2.phi, wheel2.omega, top.F, bottom.F, wheel1.h1, wheel2.h1]
simulate: {t_end: 2.0, rtol: 1e-8, dt_out: 0.005}
# multipole bench diagrams/belts/toothed_belt.yaml: speed against error over one turn of the small wheel;
# hand-written reference model: multipole_models/toothed_belt.py
reference: {kind: tight, output: wheel2.omega, t_end: 1.0, hand_model: toothed_belt}
bench: true
"""

#: diagrams/belts/compressor.yaml
COMPRESSOR = """\
name: compressor
description: >
  Belt-driven compressor (Ebert 2015, section 8.2): a motor drives the small pulley through a clutch
  that closes at 2 s and opens at 10 s; an open belt (tight span on top) drives the compressor
  pulley, whose shaft carries the slider-crank of the compressor working against an adiabatic gas
  spring, and a viscous loss; an automatic tensioner roll on a spring-loaded lever presses
  the slack span from below.
# Geometry [m]: motor pulley M at (0, 0), r = 50 mm; compressor pulley P at (0.5, 0.05), r = 150 mm;
# tensioner roll T, r = 30 mm, on a lever of 0.099 m pivoted at O = (0.32, -0.11), at 131.46 deg at the
# start (its rest angle with the belt at F0; at 135 deg T would be at (0.25, -0.04)).  The crank
# (r = 50 mm, rod 0.18 m) turns about P's centre (it sits on P's shaft; the cylinder's axis is the
# horizontal through that centre) and starts at the bottom dead centre, where the gas spring holds it.  The belt runs counter-clockwise around M and P and over the top of T
# (T turns clockwise).  Wrap senses s (+1: a counter-clockwise turn of the roll pays band out into
# the span): tight span P -> M (+1, -1), span M -> T (+1, +1), span T -> P (-1, -1).
parameters:
  EA: 1.0e5        # N: belt stiffness times length
  cd: 20.0         # N*s: belt damping times length
  F0: 444.0        # N: belt tension at the start (all spans; near the tensioner's equilibrium)
  Ts: 20.0         # N*m: motor stall torque
  ws: 150.0        # rad/s: motor no-load speed (linear speed-torque line)
  dc: 0.5          # N*m*s/rad: clutch (viscous, closed from t_on to t_off)
  t_on: 2.0        # s
  t_off: 10.0      # s
  kt: 40.0         # N*m/rad: tensioner spring
  qt: 0.5          # rad: tensioner spring preload (clockwise torque kt*qt on the lever)
  dt: 0.3          # N*m*s/rad: tensioner damper
  p0A: 60.0        # N: gas force at the bottom dead centre (469 N at the top dead centre)
  L0: 0.13         # m: gas column at the bottom dead centre (30 mm at the top dead centre)
  dl: 0.05         # N*m*s/rad: compressor losses (viscous, on the shaft)
elements:
  motor: {type: inertia, J: 0.01}
  stall: {type: torque_source, value: Ts}
  slope: {type: damper, d: Ts/ws}
  ground: {type: speed_source, value: 0.0}
  ground2: {type: speed_source, value: 0.0}
  clutch: {type: damper, law: "dc*f*(step(t, t_on) - step(t, t_off))"}
  M: {type: planar_roll, r: 0.05, J: 2.0e-4, x1: 0.0, y1: 0.0}
  P: {type: planar_roll, r: 0.15, J: 0.02, x1: 0.5, y1: 0.05}
  T: {type: planar_roll, r: 0.03, J: 5.0e-5}
  lever: {type: DAN, l: 0.09899494936611666, phi0: 2.2944, m: 0.0, J: 2.0e-4, x1: 0.32, y1: -0.11}
  spring: {type: spring, c: kt, x0: qt}
  damper: {type: damper, d: dt}
  tight: {type: planar_band, EA: EA, cd: cd, F0: F0, r1: 0.15, s1: 1, r2: 0.05, s2: -1}
  span2: {type: planar_band, EA: EA, cd: cd, F0: F0, r1: 0.05, s1: 1, r2: 0.03, s2: 1}
  span3: {type: planar_band, EA: EA, cd: cd, F0: F0, r1: 0.03, s1: -1, r2: 0.15, s2: -1}
  crank: {type: DAN, l: 0.05, phi0: 3.141592653589793, m: 2.0, J: 0.05, gy: 0.0, x1: 0.5, y1: 0.05}
  rod: {type: DDS, l: 0.18, v: 0.0, K: 1, mL: 0.6, JL: 0.003, mS: 0.4, JS: 0.0001, gy: 0.0, x2: 0.5, y2: 0.05}
  gas: {type: C, law: p0A*(L0/(L0 - q))**1.4, domain: translational}
  loss: {type: damper, d: dl}
connections:
  - [stall.p, motor.a, slope.a]
  - [slope.b, ground.p]
  - [motor.b, clutch.a]
  - [clutch.b, M.drive]
  - [M.e2, tight.e2]
  - [M.e1, span2.e1]
  - [T.e1, span2.e2]
  - [T.e2, span3.e1]
  - [P.e2, span3.e2]
  - [P.e1, tight.e1]
  - [M.c, tight.p2, span2.p1]
  - [T.c, span2.p2, span3.p1]
  - [P.c, span3.p2, tight.p1]
  - [lever.b, T.a]
  - [lever.drive, spring.a, damper.a]
  - [spring.b, damper.b, lever.support]
  - [P.drive, crank.drive, loss.a]
  - [loss.b, ground2.p]
  - [crank.b, rod.a1]
  - [rod.drive, gas.p]
outputs: [motor.omega, M.omega, P.omega, T.omega, tight.F, span2.F, span3.F, lever.phi, crank.phi]
simulate: {t_end: 14.0, dt_out: 0.005, rtol: 1.0e-6}
# multipole bench diagrams/belts/compressor.yaml: speed against error over the clutch engagement
reference:
  kind: tight
  output: tight.F
  t_end: 2.5
  no_hand_model: >-
    three planar spans with the tensioner roll on a lever (a position closure), the slider-crank and
    rod (derivative-causal masses), the gas spring and the switched clutch: written out by hand it
    would be a second implementation of the planar span geometry and the linkage reduction, not an
    independent check worth its size
bench: true
"""

#: file name under diagrams/belts/ -> YAML text
SCENES: dict = {"toothed_belt.yaml": TOOTHED_BELT, "compressor.yaml": COMPRESSOR}


def bench_scenes() -> list:
    """``(file name, YAML text, {data file name: text})`` of the belt scenes for ``multipole bench``
    (registered in the entry point group ``multipole.bench_scenes``; the bench keeps those tagged
    ``bench: true``)."""
    from .toothed_belt import table_texts
    return [("toothed_belt.yaml", TOOTHED_BELT, table_texts()), ("compressor.yaml", COMPRESSOR, {})]
