"""Write the scenes built in multipole_models (diagrams/hard/*.yaml, diagrams/drive_train.yaml and
diagrams/rlc_series.yaml) from its scene builders.

    python benchmarks/make_hard_scenes.py

tests/test_hard_cases.py checks that the files are up to date.
"""
from pathlib import Path

from multipole_models import SCENE_FILES

if __name__ == "__main__":
    root = Path(__file__).resolve().parents[1] / "diagrams"
    for name, text in SCENE_FILES.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
        print(f"wrote {path}")
