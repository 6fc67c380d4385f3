"""The run report: ``DIR/report.md`` and ``DIR/report.html`` (images linked relatively).

Sections: summary, design table (baseline vs optimum), metric table (both at the final
fidelity), constraint activity, convergence plot (``convergence.svg``, drawn here as plain SVG:
no plotting dependency), starts and their nlopt statuses, pictures (evaluator plots and the
export render), closed-loop verdicts, stage wall times and time per evaluator.
"""

from __future__ import annotations

import dataclasses
import html
import math
import statistics
import time
from pathlib import Path
from typing import Any

from hapticopt.design.atomic import write_text
from hapticopt.design.paths import inside
from hapticopt.design.units import from_si, pretty
from hapticopt.optim.results import PipelineResult, StageOutcome

#: a constraint whose normalised margin is within this is reported as active
ACTIVE_TOL = 1e-3


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


def svg_frame(width: int, height: int, left: int, top: int, plot_w: int, plot_h: int) -> list[str]:
    """Opening lines of a report figure: the SVG element, a white page and the plot area's border."""
    return [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
            f'viewBox="0 0 {width} {height}" font-family="sans-serif" font-size="11">',
            f'<rect x="0" y="0" width="{width}" height="{height}" fill="white"/>',
            f'<rect x="{left}" y="{top}" width="{plot_w}" height="{plot_h}" fill="none" stroke="#444"/>']


def convergence_svg(history: Any, *, sense_max: bool, width: int = 640, height: int = 320) -> str:
    """SVG of every point's objective (grey: feasible, red: infeasible) and the best-so-far line."""
    pts = [(r.index, r.objective, r.feasible) for r in history if math.isfinite(r.objective)]
    ml, mr, mt, mb = 70, 20, 20, 45
    w, h = width - ml - mr, height - mt - mb
    parts = svg_frame(width, height, ml, mt, w, h)
    if not pts:
        parts.append(f'<text x="{ml + 10}" y="{mt + 20}">no finite objective values</text></svg>')
        return "\n".join(parts)
    n = max(p[0] for p in pts) + 1
    ys = [p[1] for p in pts]
    lo, hi = min(ys), max(ys)
    if hi - lo < 1e-12 * max(1.0, abs(hi)):
        lo, hi = lo - 0.5, hi + 0.5
    pad = 0.05 * (hi - lo)
    lo, hi = lo - pad, hi + pad

    def sx(i: float) -> float:
        return ml + w * (i / max(1, n - 1))

    def sy(v: float) -> float:
        return mt + h * (1.0 - (v - lo) / (hi - lo))

    for k in range(5):  # y ticks
        v = lo + (hi - lo) * k / 4
        parts.append(f'<line x1="{ml - 4}" y1="{sy(v):.1f}" x2="{ml + w}" y2="{sy(v):.1f}" stroke="#ddd"/>')
        parts.append(f'<text x="{ml - 6}" y="{sy(v) + 4:.1f}" text-anchor="end">{v:.4g}</text>')
    for k in range(5):  # x ticks
        i = (n - 1) * k / 4
        parts.append(f'<text x="{sx(i):.1f}" y="{mt + h + 15}" text-anchor="middle">{i:.0f}</text>')
    parts.append(f'<text x="{ml + w / 2}" y="{height - 8}" text-anchor="middle">evaluation</text>')
    for i, v, feas in pts:
        colour = "#999" if feas else "#d33"
        parts.append(f'<circle cx="{sx(i):.1f}" cy="{sy(v):.1f}" r="2" fill="{colour}"/>')
    best = None
    line = []
    for i, v, feas in pts:
        if feas and (best is None or (v > best if sense_max else v < best)):
            best = v
        if best is not None:
            line.append(f"{sx(i):.1f},{sy(best):.1f}")
    if line:
        parts.append(f'<polyline points="{" ".join(line)}" fill="none" stroke="#1565c0" stroke-width="2"/>')
    parts.append(f'<text x="{ml + w - 4}" y="{mt + 14}" text-anchor="end" fill="#1565c0">best feasible so far</text>')
    parts.append(f'<text x="{ml + w - 4}" y="{mt + 28}" text-anchor="end" fill="#d33">infeasible point</text>')
    parts.append("</svg>")
    return "\n".join(parts)


def _tables(p: "PipelineResult") -> dict[str, tuple[list[str], list[list[str]]]]:
    prob = p.problem
    out: dict[str, tuple[list[str], list[list[str]]]] = {}
    rows = []
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
        rows.append([name, _fmt(p.baseline.metrics.get(name, float("nan"))),
                     _fmt(p.optimum.metrics.get(name, float("nan")))])
    out["metrics"] = (["metric", "baseline", "optimum"], rows)
    rows = []
    for c, (text, value, ok) in zip(prob.constraints, p.constraints_final):
        margin = -c.normalised(value) if math.isfinite(value) else float("nan")
        active = math.isfinite(margin) and abs(margin) <= max(ACTIVE_TOL, prob.optimiser.constraint_tol)
        base_v = c.metric.value(p.baseline.metrics)
        rows.append([text, _fmt(base_v), _fmt(value), f"{100 * margin:+.3g} %" if math.isfinite(margin) else "—",
                     "active" if active else ("satisfied" if ok else "VIOLATED")])
    out["constraints"] = (["constraint", "baseline", "optimum", "margin", "state"], rows)
    rows = [[str(s.start), ", ".join(_fmt(x) for x in s.x0), ", ".join(_fmt(x) for x in s.x), _fmt(s.f),
             str(s.status), str(s.n_points), s.message] for s in p.run.starts]
    out["starts"] = (["start", "x0", "x", "f", "status", "points", "message"], rows)
    rows = [[v.scene, "PASS" if v.passed else "FAIL",
             ", ".join(f"{k}={_fmt(val)}" for k, val in v.metrics.items() if not isinstance(val, (list, dict)))[:300],
             v.message] for v in p.verdicts]
    out["verdicts"] = (["scene", "verdict", "metrics", "message"], rows)
    rows = [[s.name, s.status, f"{s.wall_s:.3f}", s.message] for s in p.stages]
    out["stages"] = (["stage", "status", "wall [s]", "message"], rows)
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


def _md_table(head: list[str], rows: list[list[str]]) -> str:
    if not rows:
        return "_(none)_\n"
    esc = [[c.replace("|", "\\|") for c in r] for r in rows]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in esc]
    return "\n".join(lines) + "\n"


def _html_table(head: list[str], rows: list[list[str]]) -> str:
    if not rows:
        return "<p><em>(none)</em></p>"
    h = "".join(f"<th>{html.escape(c)}</th>" for c in head)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


_CSS = """body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:0.5em 0 1.5em}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left;
font-size:13px}th{background:#f0f0f0}img{max-width:100%;border:1px solid #ddd;margin:4px}
.ok{color:#2e7d32}.bad{color:#c62828}code{background:#f5f5f5;padding:1px 3px}"""


def write(p: "PipelineResult", *, extra_stage: tuple[str, float] | None = None,
          dest: Path | None = None) -> dict[str, str]:
    """Write convergence.svg, report.md and report.html into ``dest`` (default: the run directory;
    the pipeline passes a :func:`design.atomic.file_set` staging folder); returns role -> file."""
    out = p.out_dir if dest is None else Path(dest)
    prob = p.problem
    write_text(inside(out, "convergence.svg"), convergence_svg(p.run.history, sense_max=prob.objective.sense.value == "maximise"))
    if extra_stage is not None:
        name, t0 = extra_stage
        p = dataclasses.replace(p, stages=p.stages + (StageOutcome(name=name, status="ok",
                                                                   wall_s=time.perf_counter() - t0),))
    tables = _tables(p)
    images = [f for s in p.stages for f in s.files if f.lower().endswith((".png", ".svg", ".jpg"))]
    exports = [f for s in p.stages if s.name == "export" for f in s.files]
    obj = prob.objective.metric
    b, o = obj.value(p.baseline.metrics), obj.value(p.optimum.metrics)
    verdict_line = ("no closed-loop verification ran" if not p.verdicts else
                    f"{sum(v.passed for v in p.verdicts)}/{len(p.verdicts)} closed-loop scenes passed")
    summary = [
        f"Problem **{prob.name}** ({prob.device}, base {prob.base_source}): {prob.description}",
        f"Objective: {prob.objective.sense.value} `{obj.text}` — baseline {_fmt(b)}, optimum {_fmt(o)} "
        f"({'improved' if p.improved else 'NOT improved'}) at {prob.fidelity_final} fidelity.",
        f"Constraints at {prob.fidelity_final} fidelity: "
        f"{'all satisfied' if p.feasible_final else 'NOT all satisfied'}; {verdict_line}.",
        f"Optimiser: {prob.optimiser.algorithm.value} (local {prob.optimiser.local.value}), "
        f"{prob.optimiser.starts} start(s), seed {prob.optimiser.seed}; status {p.run.status}; "
        f"{p.run.n_evaluated} evaluations ({p.run.n_replayed} replayed from the recorder, "
        f"{p.run.n_cached} repeated points) at {prob.fidelity_optimise} fidelity in {p.run.wall_s:.2f} s.",
    ] + [f"Note: {n}" for n in p.run.notes]
    sections = [("Design", "design"), ("Metrics", "metrics"), ("Constraint activity", "constraints"),
                ("Starts", "starts"), ("Closed-loop verification", "verdicts"), ("Stage wall times", "stages"),
                ("Time per evaluator", "timings")]
    # markdown
    md = [f"# Optimisation report: {prob.name}", ""] + [f"- {s}" for s in summary] + [""]
    for title, key in sections[:3]:
        md += [f"## {title}", "", _md_table(*tables[key])]
    md += ["## Convergence", "", "![convergence](convergence.svg)", ""]
    md += ["## Starts", "", _md_table(*tables["starts"])]
    md += ["## Pictures", ""] + ([f"![{Path(f).stem}]({f})" for f in images] or ["_(none)_"]) + [""]
    if exports:
        md += ["## Exported files", ""] + [f"- [{f}]({f})" for f in exports] + [""]
    for title, key in sections[4:]:
        md += [f"## {title}", "", _md_table(*tables[key])]
    write_text(inside(out, "report.md"), "\n".join(md))
    # html
    h = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
         f"<title>Optimisation report: {html.escape(prob.name)}</title><style>{_CSS}</style></head><body>",
         f"<h1>Optimisation report: {html.escape(prob.name)}</h1><ul>"]
    for s in summary:
        s_html = html.escape(s).replace("**", "")
        h.append(f"<li>{s_html}</li>")
    h.append("</ul>")
    for title, key in sections[:3]:
        h += [f"<h2>{title}</h2>", _html_table(*tables[key])]
    h += ["<h2>Convergence</h2>", '<img src="convergence.svg" alt="convergence plot">']
    h += ["<h2>Starts</h2>", _html_table(*tables["starts"])]
    h.append("<h2>Pictures</h2>")
    h += [f'<figure><img src="{html.escape(f)}" alt="{html.escape(Path(f).stem)}"><figcaption>'
          f"{html.escape(f)}</figcaption></figure>" for f in images] or ["<p><em>(none)</em></p>"]
    if exports:
        h += ["<h2>Exported files</h2><ul>"] + [f'<li><a href="{html.escape(f)}">{html.escape(f)}</a></li>'
                                                  for f in exports] + ["</ul>"]
    for title, key in sections[4:]:
        h += [f"<h2>{title}</h2>", _html_table(*tables[key])]
    h.append("</body></html>")
    write_text(inside(out, "report.html"), "\n".join(h))
    return {"report_md": "report.md", "report_html": "report.html", "convergence": "convergence.svg"}
