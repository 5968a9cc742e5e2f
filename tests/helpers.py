"""Shared helpers for the tests: build scenes from inline YAML and run them."""
from __future__ import annotations

import math
import textwrap

import pytest

from multipole import MultipoleError, pipeline
from multipole.netlist import loads


def scene(text: str, overrides=None):
    return loads(textwrap.dedent(text), "test.yaml", overrides)


def refusal(kind: str, params: str, name: str = "x"):
    """The error a scene of the one element ``name: {type: kind, <params>}`` is refused with, after
    asserting that it names the element."""
    text = f"name: bad\nelements:\n  {name}: {{type: {kind}, {params}}}\nsimulate: {{t_end: 1.0}}\n"
    with pytest.raises(MultipoleError) as exc:
        scene(text)
    assert f"element '{name}'" in str(exc.value)
    return exc.value


def check(text: str):
    return pipeline.check(scene(text))


def codes(text: str) -> list[str]:
    return [d.code for d in check(text).diagnostics]


def run(text: str, **kw):
    sc = scene(text)
    return pipeline.run(sc, progress=False, **kw)


def circle_intersection(theta, l=0.2, l1=0.6, l2=0.5, bx=0.7):
    """Coupler and rocker angles [rad] of a four-bar (crank l at angle theta from the origin, coupler l1,
    rocker l2 pivoted at (bx, 0) [m]) in closed form, the upper assembly (K = +1)."""
    ax, ay = l * math.cos(theta), l * math.sin(theta)
    dx, dy = bx - ax, -ay
    d = math.hypot(dx, dy)
    along = (l1 * l1 - l2 * l2 + d * d) / (2 * d)
    across = math.sqrt(l1 * l1 - along * along)
    px, py = ax + along * dx / d - across * dy / d, ay + along * dy / d + across * dx / d
    return math.atan2(py - ay, px - ax), math.atan2(py, px - bx)


#: the smallest model (a force on a mass): a code writer for tests of the printed solvers
ONE_MASS = """
name: one
elements:
  f: {type: force_source, value: 1.0}
  m: {type: mass, m: 2.0}
connections:
  - [f.p, m.a]
"""


def one_mass_writer(cls=None):
    """A code writer (``multipole.codegen.Writer`` or the subclass ``cls``) of :data:`ONE_MASS`."""
    from multipole import codegen, pipeline
    return (cls or codegen.Writer)(pipeline.equations(scene(ONE_MASS)))
