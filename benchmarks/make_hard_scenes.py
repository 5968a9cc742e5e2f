"""Write diagrams/hard/*.yaml from the scene builders in multipole_models.

    python benchmarks/make_hard_scenes.py

tests/test_hard_cases.py checks that the files are up to date.
"""
from pathlib import Path

from multipole_models import HARD_SCENES

if __name__ == "__main__":
    out = Path(__file__).resolve().parents[1] / "diagrams" / "hard"
    out.mkdir(parents=True, exist_ok=True)
    for name, text in HARD_SCENES.items():
        (out / name).write_text(text, encoding="utf-8")
        print(f"wrote {out / name}")
