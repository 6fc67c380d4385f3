"""The report of a Pareto run: ``front.csv``, ``front.svg`` (plain SVG, no plotting dependency),
``report.md`` and ``report.html`` in the run directory."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hapticopt.design.atomic import write_text
from hapticopt.design.units import pretty
from hapticopt.optim.pareto import FrontPoint, FrontResult
from hapticopt.optim.problem import Problem
from hapticopt.optim.report import _CSS, _fmt, _html_table, _md_table, svg_frame
from hapticopt.optim.sweep import metric_label, rows_csv


def front_svg(result: FrontResult, problem: Problem, *, width: int = 640, height: int = 420) -> str:
    """Every feasible evaluated point (grey), the front (blue line and dots), the chosen design (red)."""
    f1, f2 = problem.objectives
    cloud = [(f1.metric.value(r.metrics), f2.metric.value(r.metrics)) for r in result.history
             if r.feasible and r.metrics]
    cloud = [p for p in cloud if all(math.isfinite(v) for v in p)]
    front = [p.objectives for p in result.front]
    pts = cloud + front
    ml, mr, mt, mb = 80, 20, 20, 50
    w, h = width - ml - mr, height - mt - mb
    parts = svg_frame(width, height, ml, mt, w, h)
    if not pts:
        parts.append(f'<text x="{ml + 10}" y="{mt + 20}">no feasible point</text></svg>')
        return "\n".join(parts)

    def span(vals: Sequence[float]) -> tuple[float, float]:
        lo, hi = min(vals), max(vals)
        if hi - lo < 1e-12 * max(1.0, abs(hi)):
            lo, hi = lo - 0.5, hi + 0.5
        pad = 0.05 * (hi - lo)
        return lo - pad, hi + pad

    (x0, x1), (y0, y1) = span([p[0] for p in pts]), span([p[1] for p in pts])

    def sx(v: float) -> float:
        return ml + w * (v - x0) / (x1 - x0)

    def sy(v: float) -> float:
        return mt + h * (1.0 - (v - y0) / (y1 - y0))

    for k in range(5):
        xv, yv = x0 + (x1 - x0) * k / 4, y0 + (y1 - y0) * k / 4
        parts.append(f'<line x1="{ml - 4}" y1="{sy(yv):.1f}" x2="{ml + w}" y2="{sy(yv):.1f}" stroke="#eee"/>')
        parts.append(f'<text x="{ml - 6}" y="{sy(yv) + 4:.1f}" text-anchor="end">{yv:.4g}</text>')
        parts.append(f'<text x="{sx(xv):.1f}" y="{mt + h + 15}" text-anchor="middle">{xv:.4g}</text>')
    parts.append(f'<text x="{ml + w / 2}" y="{height - 10}" text-anchor="middle">'
                 f'{html.escape(metric_label(f1.metric.text))} ({f1.sense.value})</text>')
    parts.append(f'<text transform="translate(14,{mt + h / 2}) rotate(-90)" text-anchor="middle">'
                 f'{html.escape(metric_label(f2.metric.text))} ({f2.sense.value})</text>')
    for a, b in cloud:
        parts.append(f'<circle cx="{sx(a):.1f}" cy="{sy(b):.1f}" r="1.5" fill="#bbb"/>')
    if front:
        line = " ".join(f"{sx(a):.1f},{sy(b):.1f}" for a, b in front)
        parts.append(f'<polyline points="{line}" fill="none" stroke="#1565c0" stroke-width="1.5"/>')
        for a, b in front:
            parts.append(f'<circle cx="{sx(a):.1f}" cy="{sy(b):.1f}" r="3" fill="#1565c0"/>')
    if result.chosen is not None:
        a, b = result.chosen.objectives
        parts.append(f'<circle cx="{sx(a):.1f}" cy="{sy(b):.1f}" r="6" fill="none" stroke="#d33" stroke-width="2"/>')
    parts.append(f'<text x="{ml + w - 4}" y="{mt + 14}" text-anchor="end" fill="#1565c0">Pareto front '
                 f'({len(front)} points)</text>')
    parts.append(f'<text x="{ml + w - 4}" y="{mt + 28}" text-anchor="end" fill="#d33">chosen design</text>')
    parts.append(f'<text x="{ml + w - 4}" y="{mt + 42}" text-anchor="end" fill="#999">feasible evaluations</text>')
    parts.append("</svg>")
    return "\n".join(parts)


def front_rows(result: FrontResult, problem: Problem) -> tuple[list[str], list[list[Any]]]:
    cols = (["run", "epsilon"] + [f"{v.key} [{pretty(v.unit)}]" for v in problem.variables]
            + [o.metric.text for o in problem.objectives] + ["chosen"])
    rows = [[p.run, p.epsilon, *p.x, *p.objectives, p is result.chosen] for p in result.front]
    return cols, rows


def front_csv(result: FrontResult, problem: Problem) -> str:
    return rows_csv(*front_rows(result, problem))


def write(result: FrontResult, problem: Problem, out: Path, *, chosen_metrics: dict[str, Any],
          chosen_feasible: bool, fidelity_final: str) -> dict[str, str]:
    """front.csv, front.svg, report.md, report.html; returns role -> file (relative)."""
    write_text(out / "front.csv", front_csv(result, problem))
    write_text(out / "front.svg", front_svg(result, problem))
    f1, f2 = problem.objectives
    cfg = problem.pareto
    chosen: FrontPoint | None = result.chosen
    how = ("knee (nearest the utopia point, objectives normalised over the front)" if cfg is None or
           cfg.choose.value == "knee" else f"weights {list(cfg.weights)} on the normalised objectives")
    summary = [
        f"Problem **{problem.name}** ({problem.device}, base {problem.base_source}): {problem.description}",
        f"Objectives: {f1.sense.value} `{f1.metric.text}` and {f2.sense.value} `{f2.metric.text}`; "
        f"{len(problem.constraints)} constraint(s).",
        f"Method: ε-constraint, {len(result.runs)} NLopt runs ({problem.optimiser.algorithm.value}); "
        f"{result.n_evaluated} evaluations ({result.n_replayed} served from earlier runs or sessions) at "
        f"{problem.fidelity_optimise} fidelity in {result.wall_s:.2f} s; {len(result.front)} non-dominated points.",
        (f"Chosen design ({how}): run {chosen.run}, {f1.metric.text} = {_fmt(chosen.objectives[0])}, "
         f"{f2.metric.text} = {_fmt(chosen.objectives[1])}; at {fidelity_final} fidelity "
         f"{_fmt(f1.metric.value(chosen_metrics))} and {_fmt(f2.metric.value(chosen_metrics))}, constraints "
         f"{'satisfied' if chosen_feasible else 'NOT satisfied'}." if chosen is not None else "No feasible point."),
    ]
    cols, rows = front_rows(result, problem)
    srows = [[str(_fmt(v)) if not isinstance(v, str) else v for v in r] for r in rows]
    run_rows = [[label, _fmt(eps), str(res.n_evaluated), str(res.n_replayed), res.status,
                 "yes" if res.feasible else "no"] for label, eps, res in result.runs]
    run_cols = ["run", "epsilon", "evaluated", "replayed", "status", "feasible"]
    md = [f"# Pareto report: {problem.name}", ""] + [f"- {s}" for s in summary] + [""]
    md += ["## Front", "", "![front](front.svg)", "", _md_table(cols, srows), "## Runs", "", _md_table(run_cols, run_rows)]
    write_text(out / "report.md", "\n".join(md))
    h = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
         f"<title>Pareto report: {html.escape(problem.name)}</title><style>{_CSS}</style></head><body>",
         f"<h1>Pareto report: {html.escape(problem.name)}</h1><ul>"]
    h += [f"<li>{html.escape(s).replace('**', '')}</li>" for s in summary]
    h += ["</ul><h2>Front</h2>", '<img src="front.svg" alt="Pareto front">', _html_table(cols, srows),
          "<h2>Runs</h2>", _html_table(run_cols, run_rows), "</body></html>"]
    write_text(out / "report.html", "\n".join(h))
    return {"front_csv": "front.csv", "front_plot": "front.svg", "report_md": "report.md",
            "report_html": "report.html"}
