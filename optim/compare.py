"""Side-by-side comparison of designs evaluated at one fidelity.

A design is named by a file (design TOML), a bundled preset, or a run directory (its
``optimum.toml``, else its ``best_infeasible.toml`` — labelled so —, else the final design recorded in its
``evaluations.sqlite``). Each is evaluated by the registry's one loop
(:func:`hapticopt.analysis.registry.evaluate_all`), through
the evaluation cache when one is given (:mod:`hapticopt.optim.cache`: a design evaluated before at
this fidelity, by a run or an earlier compare, is not recomputed, and the output says so); the
comparison lists every scalar metric and every component of a vector metric with its unit, each
design's value, and its delta from the first design (absolute and relative), then each
evaluator's status per design, and the design keys that differ.
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.registry import SAME_REL_TOL, judge, metric_direction
from hapticopt.optim import cache as evaluation_cache
from hapticopt.optim.cache import EvaluationCache
from hapticopt.design import io, tomlsafe
from hapticopt.design.atomic import write_text
from hapticopt.design.errors import InvalidInput, UnknownName
from hapticopt.design.schema import specs
from hapticopt.design.units import pretty
from hapticopt.optim.recorder import FILENAME
from hapticopt.optim.runs import RunReader
from hapticopt.optim.sweep import scalars, unit_label
from hapticopt.design.errors import short


@dataclass(frozen=True, kw_only=True)
class Named:
    """A design and where it came from."""

    label: str  # the argument as given
    source: str  # "preset prrr-paper", "file a.toml", "run cad_out/x (optimum.toml)"
    design: Any


@dataclass(frozen=True, kw_only=True)
class Row:
    metric: str  # "stiffness_limit_N_per_mm[0]"
    unit: str  # edge unit label ("N/mm", "-")
    values: tuple[float, ...]  # one per design (NaN: not computed or not ok)
    deltas: tuple[float, ...]  # values[i] − values[0]
    relative: tuple[float, ...]  # deltas[i] / |values[0]| (NaN where values[0] is 0 or NaN)
    verdicts: tuple[str, ...] = ()  # per design against the first: better, worse, changed, same or ''
    # (:func:`hapticopt.analysis.registry.judge`: the metric's direction, SAME_REL_TOL)


@dataclass(frozen=True, kw_only=True)
class Comparison:
    designs: tuple[Named, ...]
    fidelity: Fidelity
    rows: tuple[Row, ...]
    statuses: tuple[dict[str, str], ...]  # evaluator -> status, per design
    messages: tuple[dict[str, str], ...]
    design_rows: tuple[tuple[str, str, tuple[float | str, ...]], ...]  # (section.key, unit, values) that differ
    provenance: tuple[str, ...] = ()  # per design: '' computed here, else where its values came from (the cache)


def resolve(arg: str) -> Named:
    """The design named by ``arg``: a run directory, a design file, or a preset name."""
    path = Path(arg)
    if path.is_dir():
        if (path / "optimum.toml").is_file():
            return Named(label=arg, source=f"run {arg} (optimum.toml)", design=io.load_design(path / "optimum.toml"))
        if (path / "best_infeasible.toml").is_file():
            return Named(label=arg, source=f"run {arg} (best_infeasible.toml: infeasible at the final fidelity)",
                         design=io.load_design(path / "best_infeasible.toml"))
        if (path / FILENAME).is_file():
            with RunReader(path) as reader:
                final = reader.design("final")
            if final is not None:
                design = io.design_from_dict(tomlsafe.loads(final.design_toml, source=f"{arg} (recorded final design)"),
                                             source=f"{arg} (recorded final design)")
                return Named(label=arg, source=f"run {arg} (recorded final design)", design=design)
            raise InvalidInput(f"design {short(arg)}: the run has no optimum.toml and no recorded final design "
                               "(is it still running, or a sweep?)")
        raise InvalidInput(f"design {short(arg)} is a folder but not a run directory (no optimum.toml or {FILENAME})")
    if path.is_file():
        return Named(label=arg, source=f"file {arg}", design=io.load_design(path))
    if arg in io.preset_names():
        return Named(label=arg, source=f"preset {arg}", design=io.load_preset(arg))
    raise UnknownName(f"design {arg!r} is not a file, a run directory or a preset: allowed presets are "
                      f"{', '.join(io.preset_names())}")


def _rel(delta: float, ref: float) -> float:
    if not (math.isfinite(delta) and math.isfinite(ref)) or ref == 0.0:
        return math.nan
    return delta / abs(ref)


def compare(designs: Sequence[Named], *, fidelity: Fidelity = Fidelity.STANDARD,
            cache: EvaluationCache | None = None) -> Comparison:
    """Evaluate each design at ``fidelity`` (through ``cache`` when given) and line up their metrics
    (first design = reference)."""
    if len(designs) < 2:
        raise InvalidInput(f"compare needs at least 2 designs, got {len(designs)}")
    evaluations = [evaluation_cache.evaluate(d.design, fidelity, cache=cache, written_by="hapticopt compare")
                   for d in designs]
    per_design = [dict(kv for name, value in ev.metrics.items() for kv in scalars(name, value))
                  for ev in evaluations]
    # a metric of an evaluator that did not end ok is NaN there (statuses mean what they say)
    names: dict[str, None] = {}
    for m in per_design:
        for k in m:
            names.setdefault(k, None)
    rows = []
    for name in names:
        values = tuple(float(m.get(name, math.nan)) for m in per_design)
        deltas = tuple(v - values[0] for v in values)
        rows.append(Row(metric=name, unit=unit_label(name), values=values, deltas=deltas,
                        relative=tuple(_rel(d, values[0]) for d in deltas),
                        verdicts=tuple(judge(name, values[0], v) for v in values)))
    tables = [io.design_to_dict(d.design) for d in designs]
    design_rows = []
    for section in designs[0].design.SECTIONS:
        units = {s.key: s.unit for s in specs(getattr(designs[0].design, section)).values()}
        for key in tables[0].get(section, {}):
            vals = tuple(_design_value(t.get(section, {}).get(key, math.nan)) for t in tables)
            if any(v != vals[0] for v in vals):
                design_rows.append((f"{section}.{key}", pretty(units.get(key, "")), vals))
    return Comparison(designs=tuple(designs), fidelity=fidelity, rows=tuple(rows),
                      statuses=tuple({k: str(v) for k, v in ev.statuses.items()} for ev in evaluations),
                      messages=tuple({k: v for k, v in ev.messages.items() if v} for ev in evaluations),
                      design_rows=tuple(design_rows), provenance=tuple(ev.provenance for ev in evaluations))


# ------------------------------------------------------------------------------ output
def _provenance(c: Comparison) -> tuple[str, ...]:
    return c.provenance if len(c.provenance) == len(c.designs) else ("",) * len(c.designs)


def _design_value(v: Any) -> float | str:
    """A design key's value as compared: a number, or the text of a named choice (``structure.material``)."""
    return v if isinstance(v, str) else float(v)


def fmt(v: float | str) -> str:
    if isinstance(v, str):
        return v
    return "—" if not math.isfinite(v) else f"{v:.6g}"


#: how a verdict reads in markdown and in the terminal (the HTML colours the cell by its class)
MARKS = {"better": "▲ better", "worse": "▼ worse", "changed": "", "same": "", "": ""}
#: the sentence every comparison states about its colours
LEGEND = (f"Δ coloured by the metric's direction (analysis/registry.py DIRECTIONS): green better, red worse, "
          f"grey a neutral metric that changed; a change within {SAME_REL_TOL:g} of the larger value (relative) is "
          "rounding and shown as =")


def verdict(r: Row, i: int) -> str:
    return r.verdicts[i] if i < len(r.verdicts) else ""


def fmt_delta(d: float, r: float, same: bool = False) -> str:
    if not math.isfinite(d):
        return "—"
    if d == 0.0 or same:
        return "0" if d == 0.0 else "="
    return f"{d:+.4g}" + (f" ({100 * r:+.3g} %)" if math.isfinite(r) else "")


def fmt_short(d: float, r: float, same: bool = False) -> str:
    """The delta for a narrow terminal: relative where the reference is a nonzero number."""
    if not math.isfinite(d):
        return "—"
    if d == 0.0 or same:
        return "0" if d == 0.0 else "="
    return f"{100 * r:+.3g} %" if math.isfinite(r) else f"{d:+.4g}"


def as_json(c: Comparison) -> dict[str, Any]:
    def num(v: float) -> float | None:
        return v if math.isfinite(v) else None

    return {
        "fidelity": str(c.fidelity),
        "same_rel_tol": SAME_REL_TOL,
        "designs": [{"label": d.label, "source": d.source, "name": d.design.name, "device": d.design.device,
                     "statuses": s, "messages": m, "evaluation": p or "computed"}
                    for d, s, m, p in zip(c.designs, c.statuses, c.messages, _provenance(c))],
        "metrics": [{"metric": r.metric, "unit": r.unit, "values": [num(v) for v in r.values],
                     "deltas": [num(v) for v in r.deltas], "relative": [num(v) for v in r.relative],
                     "direction": str(metric_direction(r.metric)), "verdicts": list(r.verdicts)}
                    for r in c.rows],
        "design_differences": [{"key": k, "unit": u, "values": list(v)} for k, u, v in c.design_rows],
    }


def markdown(c: Comparison, renders: Sequence[str | None] = ()) -> str:
    labels = [d.label for d in c.designs]
    lines = [f"# Comparison at {c.fidelity} fidelity", ""]
    lines += [f"- **{d.label}**: {d.source} ({d.design.device}, name {d.design.name})" + (f"; values {p}" if p else "")
              for d, p in zip(c.designs, _provenance(c))]
    lines += ["", "## Metrics (Δ from " + labels[0] + ")", "", LEGEND + ".", "",
              "| metric | unit | " + " | ".join([labels[0]] + [f"{b} | Δ {b}" for b in labels[1:]]) + " |",
              "|---|---|" + "---:|" * (1 + 2 * (len(labels) - 1))]
    for r in c.rows:
        cells = [fmt(r.values[0])] + [x for i in range(1, len(labels))
                                      for x in (fmt(r.values[i]),
                                                (fmt_delta(r.deltas[i], r.relative[i], verdict(r, i) == "same")
                                                 + (" " + MARKS[verdict(r, i)] if MARKS[verdict(r, i)] else "")))]
        lines.append(f"| {r.metric} | {r.unit} | " + " | ".join(cells) + " |")
    lines += ["", "## Statuses", "", "| evaluator | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels)]
    for name in dict.fromkeys(k for s in c.statuses for k in s):
        lines.append(f"| {name} | " + " | ".join(s.get(name, "—") for s in c.statuses) + " |")
    if c.design_rows:
        lines += ["", "## Design keys that differ", "", "| key | unit | " + " | ".join(labels) + " |",
                  "|---|---|" + "---:|" * len(labels)]
        for key, unit, vals in c.design_rows:
            lines.append(f"| {key} | {unit} | " + " | ".join(fmt(v) for v in vals) + " |")
    if any(renders):
        lines += ["", "## Renders", ""]
        lines += [f"![{d.label}]({src})" for d, src in zip(c.designs, renders) if src]
    return "\n".join(lines) + "\n"


def html_page(c: Comparison, renders: Sequence[str | None] = ()) -> str:
    e = html.escape
    labels = [d.label for d in c.designs]
    out = ["<!doctype html><html><head><meta charset='utf-8'><title>hapticopt compare</title>",
           "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}"
           "td,th{border:1px solid #ccc;padding:2px 8px}td.n{text-align:right}"
           ".better{color:#1b5e20;background:#e8f5e9}.worse{color:#b71c1c;background:#ffebee}"
           ".changed{color:#555}.same{color:#999}.legend{font-size:13px;color:#555}</style></head><body>",
           f"<h1>Comparison at {e(str(c.fidelity))} fidelity</h1><ul>"]
    out += [f"<li><b>{e(d.label)}</b>: {e(d.source)} ({e(d.design.device)}, name {e(d.design.name)})</li>"
            for d in c.designs]
    out.append("</ul>")
    if any(renders):
        out.append("<div>" + "".join(f"<figure style='display:inline-block'><img src='{e(src)}' width='360'>"
                                     f"<figcaption>{e(d.label)}</figcaption></figure>"
                                     for d, src in zip(c.designs, renders) if src) + "</div>")
    out.append(f"<h2>Metrics (Δ from {e(labels[0])})</h2><p class='legend'>{e(LEGEND)}.</p><table><tr><th>metric</th><th>unit</th><th>{e(labels[0])}</th>"
               + "".join(f"<th>{e(b)}</th><th>Δ {e(b)}</th>" for b in labels[1:]) + "</tr>")
    for r in c.rows:
        cells = f"<td class='n'>{fmt(r.values[0])}</td>"
        for i in range(1, len(labels)):
            cls = verdict(r, i)
            cells += (f"<td class='n'>{fmt(r.values[i])}</td><td class='n {cls}' title='{e(cls)}'>"
                      f"{e(fmt_delta(r.deltas[i], r.relative[i], cls == 'same'))}</td>")
        out.append(f"<tr data-metric='{e(r.metric)}'><td>{e(r.metric)}</td><td>{e(r.unit)}</td>{cells}</tr>")
    out.append("</table><h2>Statuses</h2><table><tr><th>evaluator</th>" + "".join(f"<th>{e(b)}</th>" for b in labels)
               + "</tr>")
    for name in dict.fromkeys(k for s in c.statuses for k in s):
        out.append(f"<tr><td>{e(name)}</td>" + "".join(f"<td>{e(s.get(name, '—'))}</td>" for s in c.statuses)
                   + "</tr>")
    out.append("</table>")
    if c.design_rows:
        out.append("<h2>Design keys that differ</h2><table><tr><th>key</th><th>unit</th>"
                   + "".join(f"<th>{e(b)}</th>" for b in labels) + "</tr>")
        for key, unit, vals in c.design_rows:
            out.append(f"<tr><td>{e(key)}</td><td>{e(unit)}</td>" + "".join(f"<td class='n'>{fmt(v)}</td>" for v in vals)
                       + "</tr>")
        out.append("</table>")
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def write_report(c: Comparison, target: Path, *, renders: bool = False) -> list[Path]:
    """``target`` as markdown (``.md``) or HTML (``.html``); with ``renders``, a picture of each
    design (:func:`hapticopt.design.export.export`) under ``target.parent/renders/``, linked relatively."""
    target = Path(target)
    if target.suffix not in (".md", ".html"):
        raise InvalidInput(f"--report = {str(target)!r} must end in .md or .html")
    links: list[str | None] = []
    written = []
    if renders:
        from hapticopt.design import export as design_export

        for i, d in enumerate(c.designs):
            folder = target.parent / "renders" / f"{i}-{d.design.name}"
            result = design_export.export(d.design, folder, render=True)
            png = [Path(p) for p in result.files if str(p).endswith(".png")]
            links.append(str(png[0].resolve().relative_to(target.parent.resolve())) if png else None)
            written += [Path(p) for p in result.files]
    text = markdown(c, links) if target.suffix == ".md" else html_page(c, links)
    write_text(target, text)
    return [target] + written
