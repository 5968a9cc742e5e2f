"""benchmarks/run_all.py rewrites docs/performance.md: the sections other scripts measured survive,
section 3 (benchmarks/chain_scaling.py's) in its place."""
import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _load(name):
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        spec = importlib.util.spec_from_file_location(f"{name}_under_test", ROOT / "benchmarks" / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return module


def _run_all():
    return _load("run_all")


REPORT = """# Performance
## 0. How to run and read
old generated text
## 6. Compiled backends
<!-- backend-notes:begin -->
kept note
<!-- backend-notes:end -->
## Linkages (issue 12)
| four-bar | 5.2x |
### a sub-section
## 3. Scaling with model size
| N | whole process |
| 10000 | 40.3 s |
## Belts
belt figures
"""


def test_hand_measured_sections_are_carried_over_and_generated_ones_are_not():
    kept = _run_all().kept_sections(REPORT)
    assert kept == ["## Linkages (issue 12)", "| four-bar | 5.2x |", "### a sub-section", "## Belts", "belt figures"]


def test_section_3_is_chain_scalings_and_run_all_carries_it_over_unchanged():
    run_all = _run_all()
    assert run_all.section_scaling(REPORT) == ["## 3. Scaling with model size", "| N | whole process |",
                                               "| 10000 | 40.3 s |"]
    fresh = run_all.section_scaling("# Performance\n## 1. x\n")
    assert fresh[0].startswith("## 3. ") and "chain_scaling.py" in fresh[2]
    source = (ROOT / "benchmarks" / "run_all.py").read_text(encoding="utf-8")
    assert "chain_scaling.run(" not in source          # the CSV and the figure of section 3 are left alone


def test_chain_scaling_writes_only_between_its_markers():
    chain = _load("chain_scaling")
    text = f"## 3. Scaling\nintro\n{chain.TABLE_BEGIN}\n| old |\n{chain.TABLE_END}\nafter\n## 4. next\n"
    row = {"N": 10, "states": 20, "load_s": 0.02, "flatten_s": 0.007, "analyse_s": 0.008, "assemble_s": 0.006,
           "codegen_s": 0.008, "compile_s": 0.03, "choose_s": 0.001, "process_s": 2.94, "process_rss_mb": 132.4,
           "rhs_generated_us": 3.8, "jac_generated_us": float("nan"), "per_step_us": 293.0, "sim_solver": "DOP853",
           "sim_steps": 101, "load_avg": 0.4}
    out = chain.write_report(text, chain.table_lines([row], "python benchmarks/chain_scaling.py --sizes 10"))
    assert out.startswith("## 3. Scaling\nintro\n" + chain.TABLE_BEGIN + "\n| N | states |")
    assert out.endswith(chain.TABLE_END + "\nafter\n## 4. next\n") and "| old |" not in out
    assert "| 10 | 20 | 0.02 | 0.007 | 0.008 | 0.006 | 0.008 | 0.03 | 0.001 | 2.94, 132 | 3.8 | — | 293 (DOP853, 101) |" in out
    assert "`python benchmarks/chain_scaling.py --sizes 10`" in out
    with pytest.raises(SystemExit):
        chain.write_report("## 3. no markers\n", ["x"])
