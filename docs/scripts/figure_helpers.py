"""Shared helpers of the figure scripts in this folder: where the scenes and figures live, scene
parameters read from the YAML files, running a scene through the public API, saving a figure, and
the command line (figure names to make; all when none is given)."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import yaml  # noqa: E402

from multipole import load, pipeline  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "diagrams" / "weber"
FIGURES = ROOT / "docs" / "figures"


def scene_data(scene: str) -> dict:
    return yaml.safe_load((SCENES / scene).read_text(encoding="utf-8"))


def parameters(scene: str) -> dict:
    """The ``parameters:`` block of a scene file, as floats (SI units, as written in the scene)."""
    return {k: float(v) for k, v in scene_data(scene).get("parameters", {}).items()}


def element(scene: str, name: str) -> dict:
    """The numeric parameters of one element of a scene file (expressions are left out)."""
    out = {}
    for k, v in scene_data(scene)["elements"][name].items():
        try:
            out[k] = float(v)
        except (TypeError, ValueError):
            pass
    return out


def run(scene: str, overrides=None, **options):
    """Simulate a scene of ``diagrams/weber`` (``overrides`` as with ``--set``)."""
    return pipeline.run(load(SCENES / scene, overrides), progress=False, **options)


def save(fig, name: str) -> None:
    path = FIGURES / name
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print("wrote", path.relative_to(ROOT))


def finish(fig, name: str, title: str = "", axes=(), fontsize: float = 10.5) -> None:
    """Grid on ``axes``, the figure's title, tight layout, save as ``docs/figures/<name>``."""
    for ax in axes:
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=fontsize)
    fig.tight_layout()
    save(fig, name)


def main(figures: dict, argv) -> None:
    """Make the figures whose names contain one of the words in ``argv`` (all without words)."""
    FIGURES.mkdir(parents=True, exist_ok=True)
    for name, make in figures.items():
        if not argv or any(word in name for word in argv):
            make()
