"""Shared helpers for the tests: build scenes from inline YAML and run them."""
from __future__ import annotations

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
