"""Shared helpers for the tests: build scenes from inline YAML and run them."""
from __future__ import annotations

import textwrap

from multipole import pipeline
from multipole.netlist import loads


def scene(text: str, overrides=None):
    return loads(textwrap.dedent(text), "test.yaml", overrides)


def check(text: str):
    return pipeline.check(scene(text))


def codes(text: str) -> list[str]:
    return [d.code for d in check(text).diagnostics]


def run(text: str, **kw):
    sc = scene(text)
    return pipeline.run(sc, progress=False, **kw)
