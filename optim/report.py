"""The run report: ``DIR/report.md`` and ``DIR/report.html`` (images linked relatively).

Sections: summary (objective in the user's sense, an honest improvement verdict, the optimiser
as configured), design variables, metrics and constraints (units in a column of their own), the
convergence plot (``convergence.svg``: one colour per start, feasible and infeasible points
marked), the starts (feasibility, objective at each start's result), the closed-loop verdicts as
a table (scene, verdict, key numbers) with each verified scene's time histories
(``plots/loop-*.png``: position, hand force, actuator force against its reference), the export
renders, the evaluator pictures, stage wall times and time per evaluator.

Figures are drawn with matplotlib (installed with pyvista), imported lazily.
"""

from __future__ import annotations

import dataclasses
import html
import io as _io
import math
import re
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from hapticopt.analysis.registry import SAME_REL_TOL, judge
from hapticopt.design.atomic import atomic_path, write_text
from hapticopt.design.paths import inside
from hapticopt.design.units import from_si, pretty
from hapticopt.optim.problem import Algorithm, OptimiserConfig, Problem
from hapticopt.optim.results import PipelineResult, StageOutcome, TimeHistory, Verdict
from hapticopt.optim.sweep import unit_label

#: a constraint whose normalised margin is within this is reported as active
ACTIVE_TOL = 1e-3

#: verification metrics that describe the run rather than the device (left out of "key numbers")
_BOOKKEEPING = {"ticks", "plant_substeps", "wall_time_s", "controller_period_ms", "mujoco_timestep_ms", "stable"}

@dataclasses.dataclass(frozen=True)
class Judged:
    """A change cell: its text and its verdict (:func:`hapticopt.analysis.registry.judge`), the HTML class."""

    text: str
    verdict: str


#: a cell is a string, a list of lines or a judged change
Cell = str | list[str] | Judged


def _fmt(value: Any) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if math.isnan(value):
            return "—"
        return f"{value:.6g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_fmt(v) for v in value) + "]"
    return str(value)


def metric_unit(name: str) -> str:
    """The unit of a metric or metric reference as printed (``stiffness_limit_N_per_mm[0]`` → ``N/mm``,
    ``min(max_force_N)`` → ``N``, ``stiffness_error_pct`` → ``%``; ``-`` for a dimensionless one)."""
    m = re.fullmatch(r"\s*(?:min|max)\(\s*(\w+)\s*\)\s*", name)
    return unit_label(m.group(1) if m else name)


def svg_frame(width: int, height: int, left: int, top: int, plot_w: int, plot_h: int) -> list[str]:
    """Opening lines of a plain-SVG figure: the SVG element, a white page and the plot area's border."""
    return [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
            f'viewBox="0 0 {width} {height}" font-family="sans-serif" font-size="11">',
            f'<rect x="0" y="0" width="{width}" height="{height}" fill="white"/>',
            f'<rect x="{left}" y="{top}" width="{plot_w}" height="{plot_h}" fill="none" stroke="#444"/>']


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig: Any, target: Path, fmt: str) -> None:
    import matplotlib

    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "hapticopt"}), atomic_path(target) as tmp:
        fig.savefig(tmp, format=fmt, dpi=100, metadata={"Date": None} if fmt == "svg" else None)
    _pyplot().close(fig)


# ----------------------------------------------------------------------------- convergence
def convergence_figure(history: Any, *, metric: str, sense_max: bool) -> Any:
    """Matplotlib figure of every point's objective in the user's sense, one colour per start
    (filled: feasible, open: infeasible; a cross on the lower edge: a failed evaluation, no finite
    objective) and the best feasible value so far."""
    from matplotlib.lines import Line2D
    from matplotlib.ticker import MaxNLocator

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8.0, 4.2), constrained_layout=True)
    unit = metric_unit(metric)
    pts = [r for r in history if math.isfinite(r.objective)]
    n_bad = len(history) - len(pts)
    colours = plt.get_cmap("tab10").colors
    starts = sorted({r.start for r in history})
    for s in starts:
        c = colours[s % len(colours)]
        feas = [(r.index, r.objective) for r in pts if r.start == s and r.feasible]
        infeas = [(r.index, r.objective) for r in pts if r.start == s and not r.feasible]
        if feas:
            ax.scatter(*zip(*feas), s=16, color=c, zorder=3)
        if infeas:
            ax.scatter(*zip(*infeas), s=22, facecolors="none", edgecolors=[c], marker="o", linewidths=1.0, zorder=3)
    best, line = None, []
    for r in sorted(pts, key=lambda r: r.index):
        if r.feasible and (best is None or (r.objective > best if sense_max else r.objective < best)):
            best = r.objective
        if best is not None:
            line.append((r.index, best))
    if line:
        ax.step(*zip(*line), where="post", color="black", lw=1.5, zorder=2)
    bad = [r for r in history if not math.isfinite(r.objective)]
    for s in starts:  # failed evaluations: crosses on the lower edge, in their start's colour
        at = [r.index for r in bad if r.start == s]
        if at:
            ax.scatter(at, [0.0] * len(at), s=22, marker="x", color=colours[s % len(colours)], linewidths=1.0,
                       transform=ax.get_xaxis_transform(), clip_on=False, zorder=3)
    ax.set_xlabel("evaluation (order of request) [-]")
    ax.set_ylabel(f"{metric} [{unit}]")
    ax.set_title(f"objective ({'maximised' if sense_max else 'minimised'}), {len(starts)} start(s)"
                 + (f"; {n_bad} failed evaluation(s) (×, no finite objective)" if n_bad else ""), fontsize=10)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True, nbins=8))
    ax.yaxis.set_major_locator(MaxNLocator(nbins=7))
    ax.grid(True, alpha=0.3)
    handles = [Line2D([], [], ls="", marker="o", color=colours[s % len(colours)], label=f"start {s}") for s in starts]
    handles += [Line2D([], [], ls="", marker="o", color="grey", label="feasible point"),
                Line2D([], [], ls="", marker="o", markerfacecolor="none", markeredgecolor="grey",
                       label="infeasible point"),
                Line2D([], [], ls="", marker="x", color="grey", label="failed evaluation"),
                Line2D([], [], color="black", lw=1.5, label="best feasible so far")]
    fig.legend(handles=handles, loc="outside right center", fontsize=8, frameon=False)
    if not pts:
        ax.text(0.5, 0.5, "no finite objective values", transform=ax.transAxes, ha="center")
    return fig


def convergence_svg(history: Any, *, metric: str, sense_max: bool) -> str:
    """The convergence figure as SVG text (text kept as text: searchable, and testable)."""
    import matplotlib

    fig = convergence_figure(history, metric=metric, sense_max=sense_max)
    buf = _io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "hapticopt"}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    _pyplot().close(fig)
    return buf.getvalue()


# ------------------------------------------------------------------------- time histories
_AXES = (("x", "tab:blue"), ("y", "tab:orange"), ("z", "tab:green"))


def _nonzero(a: Any) -> list[int]:
    return [] if a is None else [i for i in range(a.shape[1]) if np.any(a[:, i] != 0.0)]


def history_figure(v: Verdict) -> Any:
    """Position, hand force, and actuator force against its reference over time for one scene."""
    h: TimeHistory | None = v.history
    assert h is not None
    plt = _pyplot()
    rows = [("position", "position [mm]"), ("hand_force", "force on the hand [N]")]
    if h.actuator_force is not None or h.force_reference is not None:
        rows.append(("actuator", "actuator force [N]"))
    fig, axes = plt.subplots(len(rows), 1, sharex=True, figsize=(8.0, 2.1 * len(rows) + 0.8),
                             constrained_layout=True)
    for ax, (what, label) in zip(axes, rows):
        if what == "actuator":
            comps = sorted(set(_nonzero(h.actuator_force)) | set(_nonzero(h.force_reference)))
            for i in comps:
                name, c = _AXES[i]
                if h.actuator_force is not None:
                    ax.plot(h.t, h.actuator_force[:, i], color=c, lw=1.2, label=f"{name} actual")
                if h.force_reference is not None:
                    ax.plot(h.t, h.force_reference[:, i], color=c, lw=1.0, ls="--", label=f"{name} reference")
        else:
            data = getattr(h, what)
            comps = _nonzero(data)
            for i in comps:
                name, c = _AXES[i]
                ax.plot(h.t, data[:, i], color=c, lw=1.2, label=name)
        if not comps:
            ax.text(0.5, 0.5, "zero throughout", transform=ax.transAxes, ha="center", va="center", color="grey")
        elif len(comps) < 3:
            ax.set_title("components not shown are zero throughout", fontsize=8, loc="right", color="grey")
        if h.stopped_at_s is not None:
            ax.axvline(h.stopped_at_s, color="red", ls=":", lw=1.2, label="run stopped (instability detected)")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    axes[-1].set_xlabel("time t [s]")
    every = f"one sample per {h.stride} controller ticks, " if h.stride > 1 else ""
    word = "PASS" if v.passed else "FAIL" + (f" — {v.message}" if v.message and len(v.message) <= 40 else "")
    stop = (f"; stopped at t = {h.stopped_at_s:.4g} s (instability detected), nothing drawn after"
            if h.stopped_at_s is not None else "")
    fig.suptitle(f"{v.scene}: {word} ({every}controller period {h.period_s * 1e3:g} ms{stop})", fontsize=10)
    return fig


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(text).stem if text.endswith(".toml") else text).strip("_.")[:60] or "scene"


def write_histories(verdicts: tuple[Verdict, ...], dest: Path) -> dict[str, str]:
    """``plots/loop-<i>-<scene>.png`` for every verdict with a time history; scene -> relative path."""
    out: dict[str, str] = {}
    for i, v in enumerate(verdicts):
        if v.history is None or len(v.history.t) < 2:
            continue
        rel = f"plots/loop-{i}-{_slug(v.scene)}.png"
        target = inside(dest, rel)
        target.parent.mkdir(parents=True, exist_ok=True)
        _save(history_figure(v), target, "png")
        out[v.scene] = rel
    return out


# ---------------------------------------------------------------------------------- words
def optimiser_text(cfg: OptimiserConfig, *, constrained: bool) -> str:
    """The optimiser as it runs: the local algorithm is named only where it is used (AUGLAG's
    subsidiary, the polish after a global search) — as :mod:`hapticopt.optim.driver` picks it."""
    alg = cfg.algorithm
    if alg is Algorithm.AUGLAG:
        return f"AUGLAG with subsidiary {cfg.local.value}"
    if alg.is_global:
        polish = cfg.local if (not constrained or cfg.local.handles_constraints) else Algorithm.LN_COBYLA
        why = "" if polish is cfg.local else f" ({cfg.local.value} cannot handle constraints)"
        return f"{alg.value}, then local polish with {polish.value}{why}"
    return alg.value


def _feasible(problem: Problem, metrics: dict[str, Any]) -> tuple[bool, list[str]]:
    """(all constraints hold, the violated ones' texts) at the problem's constraint tolerance."""
    bad = []
    for c in problem.constraints:
        v = c.metric.value(metrics)
        if not (math.isfinite(v) and c.normalised(v) <= problem.optimiser.constraint_tol):
            bad.append(c.text)
    return not bad, bad


def improvement_text(p: PipelineResult) -> tuple[str, str]:
    """(short verdict, sentence): better / not better only where both designs are feasible."""
    prob = p.problem
    obj = prob.objective.metric
    b, o = obj.value(p.baseline.metrics), obj.value(p.optimum.metrics)
    base_ok, base_bad = _feasible(prob, p.baseline.metrics)
    unit = metric_unit(obj.text)
    better = prob.objective.sense.value == "maximise"
    delta = ""
    if math.isfinite(b) and math.isfinite(o):
        d = o - b
        rel = f", {100 * d / abs(b):+.3g} %" if b != 0 else ""
        delta = f" (change {d:+.4g}{'' if unit == '-' else ' ' + unit}{rel})"
    if not p.feasible_final:
        return "infeasible", f"the optimum does not satisfy every constraint at {prob.fidelity_final} fidelity: no " \
                             f"improvement is claimed{delta}"
    if not base_ok:
        return "feasible (baseline infeasible)", (f"the baseline violates {', '.join(base_bad)}; the optimum satisfies "
                                                  f"every constraint, so it is not comparable on the objective "
                                                  f"alone{delta}")
    if not (math.isfinite(b) and math.isfinite(o)):
        return "not comparable", "an objective value is missing"
    if (o > b) if better else (o < b):
        return "improved", f"improved{delta}"
    return "not improved", f"not improved{delta}"


def headline(p: PipelineResult) -> str:
    """The report's opening paragraph: what was optimised, by how much, which constraints are active
    (within ACTIVE_TOL of their limit) and which variables sit at a bound, and what to check next."""
    prob = p.problem
    obj = prob.objective.metric
    unit = metric_unit(obj.text)
    b, o = obj.value(p.baseline.metrics), obj.value(p.optimum.metrics)
    word, _ = improvement_text(p)
    u = "" if unit == "-" else f" {unit}"
    by = ""
    if math.isfinite(b) and math.isfinite(o):
        by = f" from {_fmt(b)}{u} to {_fmt(o)}{u}" + (f" ({100 * (o - b) / abs(b):+.3g} %)" if b != 0 else "")
    keys = ", ".join(v.key for v in prob.variables)
    text = [f"{prob.objective.sense.value.capitalize()} {obj.text} of {prob.base_source} over {keys}: {word}{by} "
            f"at {prob.fidelity_final} fidelity."]
    tol = prob.optimiser.constraint_tol
    active, violated = [], []
    for c, (ctext, value, ok) in zip(prob.constraints, p.constraints_final):
        margin = -c.normalised(value) if math.isfinite(value) else float("nan")
        if not ok:
            violated.append(ctext)
        elif math.isfinite(margin) and abs(margin) <= max(ACTIVE_TOL, tol):
            active.append(ctext)
    if prob.constraints:
        text.append(f"Active constraints: {', '.join(active)}." if active else "No constraint is active.")
    at_bound = []
    for v in prob.variables:
        x = from_si(float(getattr(getattr(p.optimum_design, v.section), v.field)), v.unit)
        if min(x - v.lower, v.upper - x) <= 1e-6 * (v.upper - v.lower):
            at_bound.append(f"{v.key} = {_fmt(x)} {pretty(v.unit)}")
    nxt = []
    if violated:
        nxt.append(f"the violated constraints ({', '.join(violated)})")
    if at_bound:
        nxt.append(f"the variables at a bound ({', '.join(at_bound)}): widen the bound if the design allows")
    failed = [v.scene for v in p.verdicts if not v.passed]
    if failed:
        nxt.append(f"the closed-loop scenes that did not pass ({', '.join(failed)})")
    elif not p.verdicts:
        nxt.append("closed-loop behaviour (no scene was verified: `hapticopt verify`)")
    bad = [k for k, st in p.optimum.statuses.items() if str(st) != "ok"]
    if bad:
        nxt.append(f"the evaluators not ok at the optimum ({', '.join(bad)})")
    text.append("Check next: " + "; ".join(nxt) + "." if nxt else
                "Check next: the renders and the metrics table below (nothing is flagged).")
    return " ".join(text)


# --------------------------------------------------------------------------------- tables
def _start_rows(p: PipelineResult) -> tuple[list[str], list[list[Cell]]]:
    prob = p.problem
    obj = prob.objective.metric
    unit = metric_unit(obj.text)
    best = p.run.best
    rows: list[list[Cell]] = []
    for s in p.run.starts:
        own = [r for r in p.run.history if r.start == s.start]
        at = [r for r in own if tuple(r.x) == tuple(s.x)]
        rec = at[-1] if at else None
        feas_pts = [r for r in own if r.feasible and math.isfinite(r.objective)]
        if feas_pts:
            pick = max if prob.objective.sense.value == "maximise" else min
            best_own = _fmt(pick(r.objective for r in feas_pts))
        else:
            best_own = "none feasible"
        viol = (max((max(r, 0.0) for r in rec.constraints), default=0.0) if rec is not None else math.nan)
        xs = [f"{v.key}: {_fmt(a)} → {_fmt(b)} {pretty(v.unit)}" for v, a, b in zip(prob.variables, s.x0, s.x)]
        label = str(s.start) + (" (best)" if best is not None and best.start == s.start and best.x == s.x else "")
        rows.append([label, xs, _fmt(rec.objective) if rec else "—", _fmt(rec.feasible) if rec else "—",
                     f"{100 * viol:.3g} %" if math.isfinite(viol) else "—", best_own, str(s.status),
                     str(s.n_points), s.message])
    head = ["start", "variables: start → result", f"objective at result [{unit}]", "feasible",
            "largest violation", f"best feasible in start [{unit}]", "nlopt status", "points", "message"]
    return head, rows


def _key_numbers(metrics: dict[str, Any]) -> list[str]:
    out = []
    for k, val in metrics.items():
        if k in _BOOKKEEPING or isinstance(val, bool) or not isinstance(val, (int, float)):
            continue
        unit = metric_unit(k)
        out.append(f"{k} = {_fmt(float(val))}" + ("" if unit == "-" else f" {unit}"))
    return out


def _tables(p: PipelineResult) -> dict[str, tuple[list[str], list[list[Cell]]]]:
    prob = p.problem
    out: dict[str, tuple[list[str], list[list[Cell]]]] = {}
    rows: list[list[Cell]] = []
    for v in prob.variables:
        sec_b = getattr(prob.base, v.section)
        sec_o = getattr(p.optimum_design, v.section)
        b = from_si(float(getattr(sec_b, v.field)), v.unit)
        o = from_si(float(getattr(sec_o, v.field)), v.unit)
        at = " (at bound)" if min(o - v.lower, v.upper - o) <= 1e-6 * (v.upper - v.lower) else ""
        rows.append([v.key, pretty(v.unit), _fmt(v.lower), _fmt(v.upper), _fmt(b), _fmt(o) + at])
    out["design"] = (["variable", "unit", "lower", "upper", "baseline", "optimum"], rows)
    rows = []
    for name in sorted(set(p.baseline.metrics) | set(p.optimum.metrics)):
        b, o = p.baseline.metrics.get(name, float("nan")), p.optimum.metrics.get(name, float("nan"))
        rows.append([name, metric_unit(name), _fmt(b), _fmt(o), _change(name, b, o)])
    out["metrics"] = (["metric", "unit", f"baseline ({prob.fidelity_final})", f"optimum ({prob.fidelity_final})",
                       "change"], rows)
    rows = []
    for name in list(dict.fromkeys([*p.baseline.statuses, *p.optimum.statuses])):
        why = "; ".join(f"{who}: {m}" for who, m in (("baseline", p.baseline.messages.get(name, "")),
                                                     ("optimum", p.optimum.messages.get(name, ""))) if m)
        rows.append([name, str(p.baseline.statuses.get(name, "—")), str(p.optimum.statuses.get(name, "—")),
                     why or "—"])
    out["statuses"] = (["evaluator", f"baseline ({prob.fidelity_final})", f"optimum ({prob.fidelity_final})",
                        "message"], rows)
    rows = []
    tol = prob.optimiser.constraint_tol
    for c, (text, value, ok) in zip(prob.constraints, p.constraints_final):
        margin = -c.normalised(value) if math.isfinite(value) else float("nan")
        active = math.isfinite(margin) and abs(margin) <= max(ACTIVE_TOL, tol)
        base_v = c.metric.value(p.baseline.metrics)
        base_ok = math.isfinite(base_v) and c.normalised(base_v) <= tol
        rows.append([text, metric_unit(c.metric.text), _fmt(base_v), "satisfied" if base_ok else "VIOLATED",
                     _fmt(value), f"{100 * margin:+.3g} %" if math.isfinite(margin) else "—",
                     "active" if active and ok else ("satisfied" if ok else "VIOLATED")])
    out["constraints"] = (["constraint", "unit", "baseline", "baseline state", "optimum", "margin (of |limit|)",
                           "optimum state"], rows)
    out["starts"] = _start_rows(p)
    rows = [[v.scene, "PASS" if v.passed else "FAIL", str(v.metrics.get("backend", "—")),
             _key_numbers(v.metrics) or ["—"], v.message] for v in p.verdicts]
    out["verdicts"] = (["scene", "verdict", "plant", "key numbers", "reason"], rows)
    rows = [[s.name, s.status, f"{s.wall_s:.3f}", s.message] for s in p.stages]
    out["stages"] = (["stage", "status", "wall time [s]", "message"], rows)
    per: dict[str, list[float]] = {}
    for r in p.run.history:
        if str(r.source) == "evaluated":
            for k, v in r.timings_s.items():
                per.setdefault(k, []).append(float(v))
    rows = [[k, str(len(v)), f"{1e3 * statistics.median(v):.3f}", f"{1e3 * sum(v):.1f}",
             f"{1e3 * p.optimum.timings_s.get(k, float('nan')):.3f}"] for k, v in per.items()]
    out["timings"] = (["evaluator", "evaluations", f"median [ms] ({prob.fidelity_optimise})", "total [ms]",
                       f"final [ms] ({prob.fidelity_final})"], rows)
    return out


#: the sentence above the metrics table
CHANGE_LEGEND = (f"Change: optimum minus baseline, judged by each metric's direction (analysis/registry.py DIRECTIONS): "
                 f"▲ better (green), ▼ worse (red), a vector with both yellow, a neutral metric uncoloured; within "
                 f"{SAME_REL_TOL:g} relative "
                 "it is rounding, shown as =.")
#: how a verdict reads in markdown (the HTML also colours the cell by it)
_MARKS = {"better": " ▲ better", "worse": " ▼ worse"}


def _change(name: str, base: Any, opt: Any) -> Cell:
    """The optimum's change from the baseline, judged by the metric's direction: a scalar as
    ``+d (+r %) ▲ better``; a vector per component (``▲ +d (+r %); =; ▼ …``), its class ``mixed`` when some
    components are better and others worse; '—' where either is not a number (or a matrix)."""
    vector = isinstance(base, (list, tuple)) and isinstance(opt, (list, tuple)) and len(base) == len(opt)
    pairs = list(zip(base, opt)) if vector else [(base, opt)]
    if any(isinstance(v, (list, tuple, str)) for pair in pairs for v in pair):
        return Judged("—", "")
    texts, verdicts = [], []
    for a, b in pairs:
        v = judge(name, a, b)
        if v in ("", "same"):
            texts.append("—" if v == "" else "=")
        else:
            d = float(b) - float(a)
            text = f"{d:+.4g}" + (f" ({100 * d / abs(float(a)):+.3g} %)" if float(a) != 0.0 else "")
            mark = _MARKS.get(v, "")
            texts.append(text + mark if not vector else (mark.split()[0] + " " + text if mark else text))
        verdicts.append(v)
    found = {v for v in verdicts if v}
    overall = ("mixed" if {"better", "worse"} <= found else "worse" if "worse" in found else
               "better" if "better" in found else "changed" if "changed" in found else "same" if found else "")
    return Judged("; ".join(texts), overall)


def _md_cell(c: Cell) -> str:
    if isinstance(c, Judged):
        c = c.text
    text = "<br>".join(c) if isinstance(c, list) else c
    return text.replace("|", "\\|").replace("\n", " ")


def _md_table(head: list[str], rows: list[list[Cell]]) -> str:
    if not rows:
        return "_(none)_\n"
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(_md_cell(c) for c in r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def _html_cell(c: Cell) -> str:
    if isinstance(c, Judged):
        return html.escape(c.text)
    if isinstance(c, list):
        return "<br>".join(html.escape(x) for x in c)
    return html.escape(c)


def _html_table(head: list[str], rows: list[list[Cell]]) -> str:
    if not rows:
        return "<p><em>(none)</em></p>"
    h = "".join(f"<th>{html.escape(c)}</th>" for c in head)
    body = "".join("<tr>" + "".join(f"<td class='{c.verdict}'>{_html_cell(c)}</td>" if isinstance(c, Judged)
                                    else f"<td>{_html_cell(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


_CSS = """body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:0.5em 0 1.5em;max-width:100%}td,th{border:1px solid #ccc;padding:3px 8px;
text-align:left;font-size:13px;vertical-align:top;overflow-wrap:anywhere}th{background:#f0f0f0}
img{max-width:100%;height:auto;border:1px solid #ddd;margin:4px}figure{margin:0 0 1.5em}
figcaption{font-size:13px;color:#555}
.ok{color:#2e7d32}.bad{color:#c62828}.better{color:#1b5e20;background:#e8f5e9}
.worse{color:#b71c1c;background:#ffebee}.mixed{background:#fff8e1}.changed{color:#555}.same{color:#999}code{background:#f5f5f5;padding:1px 3px}"""


def _figure_html(src: str, alt: str, caption: str) -> str:
    return (f'<figure><img src="{html.escape(src)}" alt="{html.escape(alt)}"><figcaption>{html.escape(caption)}'
            "</figcaption></figure>")


def write(p: PipelineResult, *, extra_stage: tuple[str, float] | None = None,
          dest: Path | None = None) -> dict[str, str]:
    """Write convergence.svg, the time histories (plots/loop-*.png), report.md and report.html into
    ``dest`` (default: the run directory; the pipeline passes a :func:`design.atomic.file_set`
    staging folder); returns role -> file."""
    out = p.out_dir if dest is None else Path(dest)
    prob = p.problem
    obj = prob.objective.metric
    sense_max = prob.objective.sense.value == "maximise"
    write_text(inside(out, "convergence.svg"), convergence_svg(p.run.history, metric=obj.text, sense_max=sense_max))
    loops = write_histories(p.verdicts, out)
    if extra_stage is not None:
        name, t0 = extra_stage
        p = dataclasses.replace(p, stages=p.stages + (StageOutcome(name=name, status="ok",
                                                                   wall_s=time.perf_counter() - t0),))
    tables = _tables(p)
    renders = [f for s in p.stages if s.name == "export" for f in s.files if f.lower().endswith((".png", ".svg"))]
    pictures = [f for s in p.stages if s.name != "export" for f in s.files
                if f.lower().endswith((".png", ".svg", ".jpg"))]
    exports = [f for s in p.stages if s.name == "export" for f in s.files if f not in renders]
    unit = metric_unit(obj.text)
    b, o = obj.value(p.baseline.metrics), obj.value(p.optimum.metrics)
    verdict, why = improvement_text(p)
    n_pass = sum(v.passed for v in p.verdicts)
    verdict_line = ("no closed-loop verification ran" if not p.verdicts else
                    f"{n_pass}/{len(p.verdicts)} closed-loop scenes passed")
    summary = [
        f"Problem {prob.name} ({prob.device}, base {prob.base_source}): {prob.description}",
        f"Objective: {prob.objective.sense.value} {obj.text} [{unit}] — baseline {_fmt(b)}, optimum {_fmt(o)} "
        f"at {prob.fidelity_final} fidelity: {why}.",
        f"Constraints at {prob.fidelity_final} fidelity: "
        f"{'all satisfied' if p.feasible_final else 'NOT all satisfied'}; {verdict_line}.",
        f"Evaluators at {prob.fidelity_final} fidelity: " + (
            "every status ok" if all(str(v) == "ok" for v in p.optimum.statuses.values()) else
            "optimum " + ", ".join(f"{k} {v}" for k, v in p.optimum.statuses.items() if str(v) != "ok")
            + " (see Evaluator statuses; an evaluator the problem does not constrain does not make the optimum "
            "infeasible)"),
        f"Optimiser: {optimiser_text(prob.optimiser, constrained=bool(prob.constraints))}, "
        f"{prob.optimiser.starts} start(s), seed {prob.optimiser.seed}; run status {p.run.status}; "
        f"{p.run.n_evaluated} evaluations ({p.run.n_replayed} replayed from the recorder, "
        f"{p.run.n_cached} repeated points) at {prob.fidelity_optimise} fidelity in {p.run.wall_s:.2f} s.",
    ] + [f"Note: {n}" for n in p.run.notes]
    conv_caption = (f"Convergence: {obj.text} [{unit}] of every evaluated point in order of request, one colour per "
                    "start; filled markers satisfy every constraint, open markers violate one; the black line is "
                    f"the best feasible value so far ({prob.fidelity_optimise} fidelity).")
    titles = {"design": "Design variables", "statuses": "Evaluator statuses", "metrics": "Metrics",
              "constraints": "Constraints",
              "starts": "Starts", "verdicts": "Closed-loop verification", "stages": "Stage wall times",
              "timings": "Time per evaluator"}
    starts_note = (f"Objective in the user's sense ({prob.objective.sense.value}); a start's result is the point "
                   "nlopt returned; feasible means every constraint holds within the constraint tolerance "
                   f"({prob.optimiser.constraint_tol:g} of each limit).")
    # ------------------------------------------------------------------ markdown
    head = headline(p)
    md = [f"# Optimisation report: {prob.name}", "", head, ""] + [f"- {s}" for s in summary] + [""]
    for key in ("design", "statuses", "metrics", "constraints"):
        md += [f"## {titles[key]}", ""] + ([CHANGE_LEGEND, ""] if key == "metrics" else []) + [_md_table(*tables[key])]
    md += ["## Convergence", "", "![convergence](convergence.svg)", "", conv_caption, ""]
    md += ["## Starts", "", starts_note, "", _md_table(*tables["starts"])]
    md += ["## Closed-loop verification", "", _md_table(*tables["verdicts"])]
    for v in p.verdicts:
        if v.scene in loops:
            md += [f"![{v.scene}]({loops[v.scene]})", "", f"Time histories of {v.scene}.", ""]
    md += ["## Renders", ""] + ([f"![{Path(f).stem}]({f})" for f in renders] or ["_(none)_"]) + [""]
    md += ["## Evaluator pictures", ""] + ([f"![{Path(f).stem}]({f})" for f in pictures] or ["_(none)_"]) + [""]
    if exports:
        md += ["## Exported files", ""] + [f"- [{f}]({f})" for f in exports] + [""]
    for key in ("stages", "timings"):
        md += [f"## {titles[key]}", "", _md_table(*tables[key])]
    write_text(inside(out, "report.md"), "\n".join(md))
    # ---------------------------------------------------------------------- html
    h = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
         '<meta name="viewport" content="width=device-width, initial-scale=1">',
         f"<title>Optimisation report: {html.escape(prob.name)}</title><style>{_CSS}</style></head><body>",
         f"<h1>Optimisation report: {html.escape(prob.name)}</h1>",
         f"<p class='headline'><b>{html.escape(head)}</b></p><ul>"]
    h += [f"<li>{html.escape(s)}</li>" for s in summary]
    h.append("</ul>")
    for key in ("design", "statuses", "metrics", "constraints"):
        h += [f"<h2>{titles[key]}</h2>"] + ([f"<p>{html.escape(CHANGE_LEGEND)}</p>"] if key == "metrics" else []) \
            + [_html_table(*tables[key])]
    h += ["<h2>Convergence</h2>", _figure_html("convergence.svg", "convergence plot", conv_caption)]
    h += ["<h2>Starts</h2>", f"<p>{html.escape(starts_note)}</p>", _html_table(*tables["starts"])]
    h += ["<h2>Closed-loop verification</h2>", _html_table(*tables["verdicts"])]
    h += [_figure_html(loops[v.scene], f"time histories of {v.scene}",
                       f"{v.scene}: position, force on the operator's hand, actuator force (solid) against its "
                       "reference (dashed) over time.") for v in p.verdicts if v.scene in loops]
    h.append("<h2>Renders</h2>")
    h += [_figure_html(f, Path(f).stem, f) for f in renders] or ["<p><em>(none)</em></p>"]
    h.append("<h2>Evaluator pictures</h2>")
    h += [_figure_html(f, Path(f).stem, f) for f in pictures] or ["<p><em>(none)</em></p>"]
    if exports:
        h += ["<h2>Exported files</h2><ul>"] + [f'<li><a href="{html.escape(f)}">{html.escape(f)}</a></li>'
                                                  for f in exports] + ["</ul>"]
    for key in ("stages", "timings"):
        h += [f"<h2>{titles[key]}</h2>", _html_table(*tables[key])]
    h.append("</body></html>")
    write_text(inside(out, "report.html"), "\n".join(h))
    files = {"report_md": "report.md", "report_html": "report.html", "convergence": "convergence.svg"}
    files.update({f"loop {scene}": rel for scene, rel in loops.items()})
    return files
