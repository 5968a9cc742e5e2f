"""Model reduction with measured error: ``multipole reduce`` and :func:`reduce` (docs/reduce.md).

The scene is run as it is (its own inputs, horizon and solver options) and each element's
*activity* is measured: ``∫|P| dt`` over the run, ``P`` the net power into the element through its
ports (effort × flow summed over the ports, sampled on the run's output grid by
:meth:`~multipole.codegen.Model.port_values`), as a share of the sum over all elements.

The candidates are the simplifications the element library declares for each element type
(:class:`~multipole.catalogue.Reduction`: a spring made rigid, a body made massless, a damper
removed, ...); the kernel applies them to the netlist data without knowing the types.  They are
tried from the least active element up; each one is verified by simulating the edited netlist and
comparing the requested outputs with the full model's (the largest error relative to each output's
peak) and kept if that error is at most ``tol`` (greedy; the error is always measured against the
full model, never accumulated by estimate).  Passes repeat until one keeps nothing, so a damper
left across a joint made rigid is removed in the next pass.  Elements an output names are left
alone.  The result is a valid netlist, written by ``yaml.safe_dump`` from the user's own data with
the edits applied, and a :class:`Report`.
"""
from __future__ import annotations

import copy
import csv
import io
import math
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from . import pipeline
from .catalogue import Reduction, catalogue
from .errors import MultipoleError, NetlistError
from .files import atomic_output
from .netlist import Scene, load, loads


@dataclass
class Step:
    """One candidate tried: ``error`` is the largest relative output error against the full model
    (None if the candidate could not run: ``note`` says why); wall times are the integrations' [s]."""

    element: str
    type: str
    activity: float
    action: str
    accepted: bool
    states_before: int
    states_after: int | None
    error: float | None
    wall_full: float
    wall_reduced: float | None
    note: str = ""

    @property
    def speedup(self) -> float | None:
        return self.wall_full / self.wall_reduced if self.wall_reduced else None


@dataclass
class Report:
    """What :func:`reduce` did: the activity share per element, the steps tried in order, the
    reduced netlist ``text``, and the full and reduced runs (``full``, ``reduced``: Results)."""

    scene: str
    tol: float
    outputs: list
    activity: dict
    steps: list
    text: str
    full: object
    reduced: object
    states_full: int
    states_reduced: int
    error: float
    locked: list = field(default_factory=list)

    @property
    def accepted(self) -> list:
        return [s for s in self.steps if s.accepted]

    @property
    def wall_full(self) -> float:
        """Integration time of the full model [s]: the best of :data:`REPEAT` runs."""
        return float(self.full.stats.get("best_wall_time") or self.full.stats.get("wall_time") or 0.0)

    @property
    def wall_reduced(self) -> float:
        """Integration time of the reduced model [s]: the best of :data:`REPEAT` runs."""
        return float(self.reduced.stats.get("best_wall_time") or self.reduced.stats.get("wall_time") or 0.0)

    @property
    def speedup(self) -> float:
        return self.wall_full / self.wall_reduced if self.wall_reduced > 0 else math.inf

    def summary(self) -> str:
        if not self.accepted:
            return (f"{self.scene}: nothing can be simplified within tol {self.tol:g} on "
                    f"{', '.join(self.outputs)} ({len(self.steps)} candidate(s) tried); the model is unchanged")
        acts = "; ".join(f"{s.element} {s.action}" for s in self.accepted)
        return (f"{self.scene}: {len(self.accepted)} simplification(s) within tol {self.tol:g}: {acts}; states "
                f"{self.states_full} -> {self.states_reduced}, output error {self.error:.3g}, integration "
                f"{self.wall_full:.3g} s -> {self.wall_reduced:.3g} s (speed-up {self.speedup:.3g}x; solver "
                f"{self.full.solver} -> {self.reduced.solver}, steps {self.full.stats.get('steps')} -> "
                f"{self.reduced.stats.get('steps')})")

    ROW = ("step", "element", "type", "activity_share", "action", "accepted", "states_before", "states_after",
           "output_error", "wall_full_s", "wall_reduced_s", "speedup", "note")

    def rows(self) -> list:
        out = []
        for k, s in enumerate(self.steps, 1):
            out.append([k, s.element, s.type, f"{s.activity:.3g}", s.action, "yes" if s.accepted else "no",
                        s.states_before, "" if s.states_after is None else s.states_after,
                        "" if s.error is None else f"{s.error:.3g}", f"{s.wall_full:.3g}",
                        "" if s.wall_reduced is None else f"{s.wall_reduced:.3g}",
                        "" if s.speedup is None else f"{s.speedup:.3g}", s.note])
        return out

    def to_csv(self) -> str:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(self.ROW)
        w.writerows(self.rows())
        return buf.getvalue()

    def to_markdown(self) -> str:
        lines = [f"# Reduction of {self.scene}", "", self.summary(), "",
                 f"Outputs compared: {', '.join(self.outputs)}; tolerance {self.tol:g} (largest error relative to "
                 "each output's peak, measured by re-simulation against the full model).", ""]
        if self.locked:
            lines += [f"Left alone (named by an output): {', '.join(self.locked)}.", ""]
        lines += ["## Activity (share of the sum of ∫|P| dt)", "", "| element | share |", "|---|---|"]
        lines += [f"| {e} | {a:.3g} |" for e, a in sorted(self.activity.items(), key=lambda kv: -kv[1])]
        lines += ["", "## Steps", "", "| " + " | ".join(self.ROW) + " |", "|" + "---|" * len(self.ROW)]
        lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in self.rows()]
        return "\n".join(lines) + "\n"

    def plot(self, path=None):
        """The outputs of the full and the reduced model over time, one panel each
        (:func:`multipole.plotting.time_plot`)."""
        from .plotting import time_plot
        title = (f"{self.scene}: full ({self.states_full} states) vs reduced ({self.states_reduced} states), "
                 f"output error {self.error:.2g} (tol {self.tol:g})")
        footer = self.summary()
        return time_plot({"full": self.full, "reduced": self.reduced}, path, title, footer)

    def write(self, folder) -> list:
        """``report.md``, ``report.csv`` and ``outputs.png`` in ``folder`` (created); the paths."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        paths = [folder / "report.md", folder / "report.csv", folder / "outputs.png"]
        for path, text in zip(paths, (self.to_markdown(), self.to_csv())):
            with atomic_output(path) as tmp:
                Path(tmp).write_text(text, encoding="utf-8")
        self.plot(paths[2])
        return paths


def check_tol(tol) -> float:
    """``tol`` as a float in (0, 1), else an error (exit 2)."""
    try:
        value = float(tol)
    except (TypeError, ValueError):
        value = math.nan
    if not (0.0 < value < 1.0):
        raise MultipoleError("bad_option", f"--tol must be a relative error between 0 and 1 (exclusive), got {tol!r}",
                             "e.g. --tol 1e-3")
    return value


# -- the netlist edits -------------------------------------------------------------------------------

def _ports_of(data: dict, element: str) -> list:
    """``(group index, reference)`` of every connection reference to a port of ``element``."""
    return [(k, ref) for k, group in enumerate(data["connections"]) for ref in group
            if isinstance(ref, str) and ref.rsplit(".", 1)[0] == element]


def apply(data: dict, element: str, red: Reduction, target: str | None = None) -> dict | None:
    """A copy of the netlist ``data`` with ``red`` applied to ``element`` (a level reduction: to the
    level ``target``); None where it does not apply (connections not written as lists of
    ``element.port``, the element not at a more detailed level than ``target``)."""
    conns = data.get("connections")
    if not isinstance(conns, list) or not all(isinstance(g, list) for g in conns):
        return None
    new = copy.deepcopy(data)
    entry = new["elements"][element]
    if red.level:
        levels = list(red.levels)
        current = entry.get(red.level) if isinstance(entry, dict) else None
        if current not in levels or target not in levels or levels.index(target) <= levels.index(current):
            return None
        if red.adapt is not None:
            entry = red.adapt(dict(entry), target)
            if entry is None:
                return None
        entry[red.level] = target
        for name in dict(red.drop).get(target, ()):
            entry.pop(name, None)
        new["elements"][element] = entry
        return new
    if red.adapt is not None:                 # the element rewritten in place (a chain lumped)
        entry = red.adapt(dict(entry), None) if isinstance(entry, dict) else None
        if entry is None:
            return None
        new["elements"][element] = entry
        return new
    groups = new["connections"]
    mine = {f"{element}.{p}" for p in red.join}
    if red.join:
        merged, first = [], None
        for k, group in enumerate(groups):
            if any(ref in mine for ref in group):
                first = k if first is None else first
                merged += [ref for ref in group if ref not in mine and ref not in merged]
        if first is None:
            return None
        groups = [merged if k == first else g for k, g in enumerate(groups)
                  if k == first or not any(ref in mine for ref in g)]
    owned = {ref for _k, ref in _ports_of({"connections": groups}, element)}
    groups = [[ref for ref in g if ref not in owned] for g in groups]
    new["connections"] = [g for g in groups if len(g) >= 2]
    del new["elements"][element]
    return new


def dump(data: dict, header: str = "") -> str:
    """The netlist ``data`` as YAML (``yaml.safe_dump``, keys in the user's order), after a comment."""
    text = yaml.safe_dump(data, sort_keys=False, default_flow_style=None, allow_unicode=True, width=110)
    return "".join(f"# {line}\n" for line in header.splitlines()) + text


# -- measurements ----------------------------------------------------------------------------------

def activity(scene: Scene, result, outputs) -> dict:
    """``{element: share}``: ∫|P| dt of each top-level element of ``scene`` over ``result``'s grid
    (``result`` from a run with every state: ``pipeline.run(..., prune=False)``), divided by the sum
    over the elements."""
    m = pipeline.model(scene, outputs, prune=False)
    flat = pipeline.equations(scene).analysis.flat
    ports = {}
    for path, inner in flat.external_ports.items():
        owner = path.rsplit(".", 1)[0]
        if owner in scene.element_types:
            ports.setdefault(owner, []).append(inner)
    power = {e: np.zeros(len(result.t)) for e in ports}
    for k, (t, x) in enumerate(zip(result.t, result.states)):
        values = m.port_values(t, x)
        for e, inner in ports.items():
            power[e][k] = sum(values.get(f"{p}.e", 0.0) * values.get(f"{p}.f", 0.0) for p in inner)
    integral = {e: float(np.trapezoid(np.abs(p), result.t)) if len(result.t) > 1 else 0.0 for e, p in power.items()}
    total = sum(integral.values())
    return {e: (v / total if total > 0 else 0.0) for e, v in integral.items()}


def output_error(full, reduced, outputs) -> float:
    """Largest ``|y_reduced - y_full|`` over the grid divided by the peak ``|y_full|``, over the
    outputs (absolute where an output is zero throughout)."""
    worst = 0.0
    for name in outputs:
        ref, got = np.asarray(full.outputs[name]), np.asarray(reduced.outputs[name])
        if ref.shape != got.shape:
            return math.inf
        peak = float(np.max(np.abs(ref))) if ref.size else 0.0
        worst = max(worst, float(np.max(np.abs(got - ref))) / (peak if peak > 0 else 1.0))
    return worst if math.isfinite(worst) else math.inf


def _run(scene: Scene, outputs, prune: bool = True):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return pipeline.run(scene, outputs=outputs, progress=False, prune=prune)


#: runs timed for the report's full and reduced integration times (the best one counts: the
#: machine may be busy; the compiled model is reused, so the repeats cost integration only)
REPEAT = 3


def _best_of(scene: Scene, outputs, result):
    """``result`` with ``stats["best_wall_time"]``: the least wall time of it and REPEAT - 1 more runs."""
    walls = [float(result.stats.get("wall_time") or 0.0)]
    walls += [float(_run(scene, outputs).stats.get("wall_time") or 0.0) for _ in range(REPEAT - 1)]
    result.stats["best_wall_time"] = min(walls)
    return result


class _Bar:
    """A one-line progress bar on stderr (only on a terminal unless asked for)."""

    def __init__(self, enabled):
        self.enabled = sys.stderr.isatty() if enabled is None else bool(enabled)

    def show(self, done: int, total: int, what: str) -> None:
        if self.enabled:
            filled = int(24 * done / max(total, 1))
            print(f"\rreduce [{'#' * filled}{'.' * (24 - filled)}] {done}/{total} {what[:40]:<40}", end="",
                  file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.enabled:
            print(file=sys.stderr, flush=True)


def reduce(scene, tol: float = 1e-3, outputs=None, progress=None, overrides=None):
    """Simplify ``scene`` (a netlist path, or a :class:`~multipole.netlist.Scene` loaded from a file)
    as far as the outputs allow: ``(reduced Scene, Report)`` (see the module's doc).

    ``tol``: largest relative output error accepted, in (0, 1); ``outputs``: names to compare
    (default: the scene's outputs).  Errors: ``bad_option`` for ``tol``, ``no_outputs``,
    ``unknown_output`` (exit 2), :class:`~multipole.errors.IllPosedError` for a scene that is not
    well-posed (exit 1).
    """
    tol = check_tol(tol)
    path = str(scene.path if isinstance(scene, Scene) else scene)
    if not Path(path).is_file():
        raise NetlistError("no_file", f"reduce edits a netlist file, and {path!r} is not one",
                           "give the path of the netlist (a Scene loaded with multipole.load)", path)
    full_scene = scene if isinstance(scene, Scene) else load(path, overrides)
    with open(path, encoding="utf-8") as fh:
        data = yaml.safe_load(fh)
    for name, value in (overrides or {}).items():       # --set element.param=value, as the loader applies it
        try:
            value = float(value) if math.isfinite(float(value)) else value    # a number stays a number
        except (TypeError, ValueError):
            pass
        element, _, param = name.partition(".")
        if isinstance(data.get("elements", {}).get(element), dict) and param:
            data["elements"][element][param] = value
        elif isinstance(data.get("parameters"), dict):
            data["parameters"][name] = value
    outputs = list(outputs or full_scene.outputs)
    if list(data.get("outputs") or []) != outputs:
        data["outputs"] = list(outputs)           # the reduced netlist offers what it was checked on
    if not outputs:
        raise NetlistError("no_outputs", "reduce compares outputs, and none are given",
                           "add outputs: [...] to the netlist or give --outputs", path)
    eq = pipeline.equations(full_scene)           # IllPosedError if not well-posed
    for name in outputs:
        try:
            eq.output(name)
        except MultipoleError as exc:
            raise NetlistError("unknown_output", exc.message, exc.fix, path) from None
    bar = _Bar(progress)
    bar.show(0, 1, "full model")
    full = _run(full_scene, outputs, prune=False)
    shares = activity(full_scene, full, outputs)
    timed = _best_of(full_scene, outputs, _run(full_scene, outputs))     # the model simulate runs
    wall_full = timed.stats["best_wall_time"]
    types = catalogue()
    observed = {o.split(".")[0] for o in outputs}
    locked = sorted(e for e in full_scene.element_types if e in observed
                    and any(r.join or not (r.level or r.adapt) for r in types[full_scene.element_types[e]].reductions))
    steps, current, best, states_now, error_now = [], data, timed, len(timed.state_names), 0.0
    broken, rejected = set(), set()       # could not run (not retried); too large an error (retried after a change)
    changed = True
    while changed:
        changed = False
        todo = [c for c in _candidates(current, types, observed, shares) if c not in broken and c not in rejected]
        for k, (element, red, target) in enumerate(todo):
            bar.show(k, len(todo), f"{element} {red.action}")
            edited = apply(current, element, red, target)
            if edited is None:
                broken.add((element, red, target))
                continue
            step = Step(element, str(current["elements"][element].get("type")), shares.get(element, 0.0),
                        _action(current, element, red, target), False, states_now, None, None, wall_full, None)
            steps.append(step)
            try:
                result = _run(loads(dump(edited), path), outputs)
            except (MultipoleError, ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
                code = getattr(exc, "code", type(exc).__name__)        # a candidate that fails is rejected
                step.note = f"{code}: {getattr(exc, 'message', str(exc))}"[:160]
                broken.add((element, red, target))
                continue
            step.states_after = len(result.state_names)
            step.error = output_error(full, result, outputs)
            step.wall_reduced = float(result.stats.get("wall_time") or 0.0)
            step.accepted = step.error <= tol
            if not step.accepted:
                step.note = f"error {step.error:.3g} > tol {tol:g}"
                rejected.add((element, red, target))
                continue
            current, best, states_now, error_now, changed = edited, result, step.states_after, step.error, True
            rejected.clear()
            break
    bar.close()
    header = (f"reduced by multipole reduce from {Path(path).name} at tol {tol:g} on {', '.join(outputs)}: "
              + ("; ".join(f"{s.element} {s.action}" for s in steps if s.accepted) or "nothing simplified")
              + f"\nmeasured output error {error_now:.3g} (largest, relative to each output's peak)")
    if any(s.accepted for s in steps):
        current = dict(current)
        current.pop("reference", None)        # it describes the full model
        text = dump(current, header)
        reduced_scene = loads(text, path)
    else:
        text = Path(path).read_text(encoding="utf-8")     # unchanged: the user's file as it is
        reduced_scene = full_scene
    if best is not timed:
        best = _best_of(reduced_scene, outputs, best)
    report = Report(full_scene.name, tol, outputs, shares, steps, text, timed, best, len(timed.state_names),
                    states_now, error_now, locked)
    return reduced_scene, report


def _candidates(data: dict, types: dict, observed: set, shares: dict) -> list:
    """``[(element, Reduction, target level or None)]`` the netlist ``data`` offers, least active
    element first; an element named by an output is only offered a simpler level.  A level reduction gives one candidate
    per simpler level, the nearest first."""
    out = []
    for element, entry in data.get("elements", {}).items():
        kind = types.get(entry.get("type")) if isinstance(entry, dict) else None
        if kind is None:
            continue
        for red in kind.reductions:
            if element in observed and (red.join or not (red.level or red.adapt)):
                continue                # it would disappear; a simpler form may still offer the output
            if not red.level:
                out.append((element, red, None))
            elif entry.get(red.level) in red.levels:
                levels = list(red.levels)
                out += [(element, red, t) for t in levels[levels.index(entry[red.level]) + 1:]]
    return sorted(out, key=lambda c: shares.get(c[0], 0.0))     # stable: the nearest level first


def _action(data, element, red: Reduction, target) -> str:
    return f"level {data['elements'][element][red.level]} -> {target}" if red.level else red.action


def cmd_reduce(args) -> int:
    """``multipole reduce FILE [--tol REL] [--outputs ...] [-o reduced.yaml] [--report DIR]``."""
    from .cli import _overrides, check_output_path
    check_tol(args.tol)
    check_output_path(args.output, (".yaml", ".yml"), "-o")
    if args.report and Path(args.report).exists() and not Path(args.report).is_dir():
        raise MultipoleError("bad_output", f"--report {args.report}: is a file, not a folder", "give a folder name")
    _scene, report = reduce(args.file, args.tol, args.outputs, progress=False if args.quiet else None,
                            overrides=_overrides(args.set))
    print(report.summary())
    if report.locked:
        print(f"  left alone (named by an output): {', '.join(report.locked)}")
    for s in report.steps:
        verdict = "kept" if s.accepted else "rejected"
        error = f"error {s.error:.3g}" if s.error is not None else s.note
        print(f"  {s.element} ({s.type}, activity {s.activity:.3g}): {s.action}: {verdict}, {error}")
    if args.output:
        with atomic_output(args.output) as tmp:
            Path(tmp).write_text(report.text, encoding="utf-8")
        print(f"wrote {args.output}" + ("" if report.accepted else " (unchanged)"))
    if args.report:
        for p in report.write(args.report):
            print(f"wrote {p}")
    return 0


__all__ = ["Report", "Step", "reduce", "apply", "activity", "output_error", "check_tol"]
