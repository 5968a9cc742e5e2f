"""The pipeline's stages import only from earlier stages (issue 10: "no stage reaches back into a
later one").  Every relative import counts, also those inside functions."""
import ast
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "multipole"
#: the stages in pipeline order: load, analyse (with its registered checks), assemble, prune, generate
#: code, simulate.  ``network`` (the data model every stage shares), ``errors``, ``diagnostics`` and
#: the leaf modules (``solvers``, ``stages``, ``expressions``…) are not stages.
STAGES = ["netlist", "causality", "equations", "pruning", "codegen", "simulate"]


def relative_imports(module: str) -> set:
    """Top-level names of the package's modules that ``module`` imports, anywhere in its text."""
    tree = ast.parse((PACKAGE / f"{module}.py").read_text())
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            found |= {node.module.split(".")[0]} if node.module else {a.name for a in node.names}
    return found


def test_relative_imports_sees_imports_inside_functions(tmp_path, monkeypatch):
    """The scanner itself: an import inside a function is found (else the rule below checks nothing)."""
    (tmp_path / "probe.py").write_text("def f():\n    from .simulate import x\n    from . import codegen\n")
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", tmp_path)
    assert relative_imports("probe") == {"simulate", "codegen"}


@pytest.mark.parametrize("stage", STAGES[:-1])
def test_no_stage_imports_a_later_one(stage):
    later = set(STAGES[STAGES.index(stage) + 1:])
    assert not relative_imports(stage) & later, f"{stage} imports the later stage(s) {relative_imports(stage) & later}"
