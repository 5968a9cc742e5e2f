"""benchmarks/run_all.py rewrites docs/performance.md: the sections other scripts measured survive."""
import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run_all():
    spec = importlib.util.spec_from_file_location("run_all_under_test", ROOT / "benchmarks" / "run_all.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


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
stale generated text
## Belts
belt figures
"""


def test_hand_measured_sections_are_carried_over_and_generated_ones_are_not():
    kept = _run_all().kept_sections(REPORT)
    assert kept == ["## Linkages (issue 12)", "| four-bar | 5.2x |", "### a sub-section", "## Belts", "belt figures"]

