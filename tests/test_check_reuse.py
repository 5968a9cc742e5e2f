"""``multipole check`` then a model build in one process derives the equations once: the analysis
of a scene's last check is what pipeline.equations uses (docs/performance.md "Linkages")."""
from multipole import pipeline
from tests.helpers import scene

TEXT = """
name: reuse
elements:
  f: {type: force_source, value: 1.0}
  m: {type: mass, m: 2.0}
connections:
  - [f.p, m.a]
"""


def test_equations_use_the_last_check_of_the_scene():
    sc = scene(TEXT)
    analysis = pipeline.check(sc)
    eq = pipeline.equations(sc)
    assert eq is analysis.assembled and eq.analysis is analysis


def test_another_scene_is_checked_anew():
    """An override changes the scene's digest: its equations come from a check of their own."""
    first = pipeline.check(scene(TEXT))
    other = scene(TEXT, {"m.m": 3.0})
    eq = pipeline.equations(other)
    assert eq.analysis is not first and eq.params != first.assembled.params
