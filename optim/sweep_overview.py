"""A sweep's overview page: every metric that varies, against the swept key(s), on one sheet.

:func:`write` makes ``overview.png`` and ``overview.html`` in the sweep's directory from the table of
:func:`hapticopt.optim.sweep.table` (the same numbers as ``sweep.csv``):

- 1-D sweep: one panel per metric, the metric against the swept key, its unit on the axis.
- 2-D sweep: one heat map per metric (first key on the vertical axis, second on the horizontal), the unit
  on the colour bar.
- Points are classed as **not ok** (the outcome is not ``ok``: the design cannot be built or an evaluator's
  numbers do not hold, so the point has no numbers) or **not met** (``ok``, but an evaluator reports
  ``not-met`` or ``collides``: its numbers hold, a requirement does not). 1-D: not-ok spans are shaded red
  and not-met spans orange (each point's span reaches halfway to its neighbours); 2-D: not-ok cells
  carry a red ×, not-met cells an orange ○.

A metric is plotted when its finite values over the sweep differ by more than :data:`CONSTANT_REL` of
their magnitude; the page lists the
others (constant, or no finite value) and every point that is not ok with its reason, and counts per reason.
"""

from __future__ import annotations

import html
import math
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hapticopt.analysis import registry
from hapticopt.design.atomic import atomic_path, write_text

#: at most this many panels on the sheet (a 3-PRRR draft sweep has about 50 scalar columns); the page
#: names the metrics left out past it
MAX_PANELS = 64
#: at most this many not-ok points listed one by one on the page (all are counted per reason)
MAX_LISTED = 50
#: a metric whose values over the sweep differ by at most this fraction of their largest magnitude is constant
#: (rounding: device_mass_sea_modules_kg moves by about 1e-16 relative over a beta sweep)
CONSTANT_REL = 1e-9
PNG, HTML = "overview.png", "overview.html"
OK, NOT_OK, NOT_MET = 0, 1, 2
_COLOURS = {NOT_OK: "#d32f2f", NOT_MET: "#f57c00"}
_LEGEND = {NOT_OK: "not ok (no numbers: the design cannot be built or an evaluator failed)",
           NOT_MET: "not met (an evaluator reports not-met or collides; its numbers hold)"}


def unit(name: str) -> str:
    """The metric's unit as printed (:func:`hapticopt.analysis.registry.metric_unit`), ``-`` when dimensionless."""
    return registry.metric_unit(name) or "-"


def point_class(result: Any) -> int:
    """:data:`OK`, :data:`NOT_OK` or :data:`NOT_MET` for one point's result."""
    if str(result.outcome) != "ok":
        return NOT_OK
    return NOT_MET if any(str(s) != "ok" for s in result.statuses.values()) else OK


def reason(result: Any) -> str:
    """One short reason per point, for the counts: the outcome, or the evaluator statuses that are not ok."""
    if str(result.outcome) != "ok":
        first = result.message.split(";")[0].split(" — ")[0].strip()
        return f"{result.outcome}: {first}" if first else str(result.outcome)
    return ", ".join(f"{k}: {v}" for k, v in result.statuses.items() if str(v) != "ok")


def chosen(cols: Sequence[str], data: np.ndarray) -> tuple[list[int], list[str], list[str]]:
    """Column indices to plot (finite values that differ beyond :data:`CONSTANT_REL`), and the names left out as constant /
    without a finite value."""
    plotted, constant, empty = [], [], []
    for j, col in enumerate(cols):
        y = data[:, j]
        finite = y[np.isfinite(y)]
        if finite.size == 0:
            empty.append(col)
        elif finite.max() - finite.min() > CONSTANT_REL * float(np.max(np.abs(finite))):
            plotted.append(j)
        else:
            constant.append(col)
    return plotted, constant, empty


def _runs(classes: np.ndarray) -> list[tuple[int, int, int]]:
    """Maximal runs ``(first, last, class)`` of equal non-ok classes (one shaded span per run)."""
    out, i = [], 0
    while i < len(classes):
        k = int(classes[i])
        j = i
        while j + 1 < len(classes) and classes[j + 1] == k:
            j += 1
        if k != OK:
            out.append((i, j, k))
        i = j + 1
    return out


def _edges(x: np.ndarray) -> np.ndarray:
    """Cell edges of the points ``x`` (halfway between neighbours, a half step past each end)."""
    if len(x) == 1:
        return np.array([x[0] - 0.5, x[0] + 0.5])
    mid = (x[1:] + x[:-1]) / 2
    return np.concatenate([[x[0] - (mid[0] - x[0])], mid, [x[-1] + (x[-1] - mid[-1])]])


def _panel_1d(ax: Any, axis: Any, y: np.ndarray, classes: np.ndarray, col: str) -> None:
    x = np.asarray(axis.values, dtype=float)
    edges = _edges(x)
    for first, last, k in _runs(classes):
        ax.axvspan(edges[first], edges[last + 1], color=_COLOURS[k], alpha=0.18, lw=0)
    shown = np.where(classes == NOT_OK, np.nan, y)
    ax.plot(x, shown, "-", color="#1f77b4", lw=1.2)
    ms = 3 if len(x) <= 200 else 0
    if ms:
        ax.plot(x[classes == OK], y[classes == OK], "o", color="#1f77b4", ms=ms)
        ax.plot(x[classes == NOT_MET], y[classes == NOT_MET], "o", mfc="none", color=_COLOURS[NOT_MET], ms=ms + 2)
    ax.set_xlabel(axis.label, fontsize=8)
    ax.set_ylabel(unit(col), fontsize=8)
    ax.grid(True, alpha=0.3)


def _panel_2d(fig: Any, ax: Any, axes: Sequence[Any], y: np.ndarray, classes: np.ndarray, col: str) -> None:
    xs, ys = np.asarray(axes[1].values, dtype=float), np.asarray(axes[0].values, dtype=float)
    z = y.reshape(axes[0].n, axes[1].n)
    k = classes.reshape(axes[0].n, axes[1].n)
    ax.set_facecolor("#e0e0e0")  # cells without a number
    mesh = ax.pcolormesh(xs, ys, np.ma.masked_invalid(np.where(k == NOT_OK, np.nan, z)), shading="nearest",
                         cmap="viridis")
    fig.colorbar(mesh, ax=ax).set_label(unit(col), fontsize=8)
    gx, gy = np.meshgrid(xs, ys)
    if len(xs) * len(ys) <= 2500:  # markers on a finer grid would hide the map: the grey cells still say it
        ax.plot(gx[k == NOT_OK], gy[k == NOT_OK], "x", color=_COLOURS[NOT_OK], ms=5)
        ax.plot(gx[k == NOT_MET], gy[k == NOT_MET], "o", mfc="none", color=_COLOURS[NOT_MET], ms=5)
    ax.set_xlabel(axes[1].label, fontsize=8)
    ax.set_ylabel(axes[0].label, fontsize=8)


def _title(result: Any, classes: np.ndarray) -> str:
    sw = result.sweep
    keys = " × ".join(f"{a.key} ({a.n})" for a in sw.axes)
    n_met, n_unmet = int(np.sum(classes == OK)), int(np.sum(classes == NOT_MET))
    # "ok" counts outcomes, as the command's summary line does; the not-met ones among them are named
    return (f"{sw.base.name}: sweep of {keys} at {sw.fidelity} fidelity — {len(classes)} points, "
            f"{n_met + n_unmet} ok ({n_unmet} of them with a requirement not met), "
            f"{int(np.sum(classes == NOT_OK))} not ok")


def write_png(result: Any, cols: Sequence[str], data: np.ndarray, classes: np.ndarray, plotted: Sequence[int],
              path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    axes = result.sweep.axes
    n = max(1, len(plotted))
    ncols = min(4, n)
    nrows = math.ceil(n / ncols)
    fig, grid = plt.subplots(nrows, ncols, figsize=(4.2 * ncols, 3.0 * nrows + 0.9), dpi=80, squeeze=False)
    for a in grid.flat[n:]:
        a.set_visible(False)
    if not plotted:
        grid[0, 0].text(0.5, 0.5, "no metric has two different finite values\nover this sweep", ha="center",
                        va="center", transform=grid[0, 0].transAxes)
        grid[0, 0].set_axis_off()
    for ax, j in zip(grid.flat, plotted):
        col = cols[j]
        if len(axes) == 1:
            _panel_1d(ax, axes[0], data[:, j], classes, col)
        else:
            _panel_2d(fig, ax, axes, data[:, j], classes, col)
        ax.set_title(f"{col} [{unit(col)}]", fontsize=9)
        ax.tick_params(labelsize=7)
    handles = [Patch(color=_COLOURS[k], alpha=0.5, label=_LEGEND[k]) for k in (NOT_OK, NOT_MET) if np.any(classes == k)]
    top = 1 - 0.9 / (3.0 * nrows + 0.9)
    fig.suptitle(_title(result, classes), fontsize=11, y=0.995)
    if handles:
        fig.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, top + 0.2 / (3.0 * nrows + 0.9)),
                   ncol=len(handles), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, top - 0.1 / (3.0 * nrows + 0.9)))
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)


def _num(v: float) -> str:
    return "—" if not math.isfinite(v) else f"{v:.6g}"


def html_page(result: Any, cols: Sequence[str], data: np.ndarray, classes: np.ndarray, plotted: Sequence[int],
              constant: Sequence[str], empty: Sequence[str]) -> str:
    e = html.escape
    sw = result.sweep
    out = ["<!doctype html><html><head><meta charset='utf-8'><title>hapticopt sweep overview</title>",
           "<style>body{font-family:sans-serif;margin:2em;max-width:1400px}table{border-collapse:collapse}"
           "td,th{border:1px solid #ccc;padding:2px 8px}td.n{text-align:right}img{max-width:100%}"
           ".notok{color:#b71c1c}.notmet{color:#e65100}.legend{font-size:13px;color:#555}</style></head><body>",
           f"<h1>{e(_title(result, classes))}</h1>",
           "<p>Axes: " + "; ".join(f"<b>{e(a.label)}</b> {a.variable.lower:g} to {a.variable.upper:g} in {a.n} points"
                                   for a in sw.axes)
           + (f". Evaluators: {e(', '.join(sw.only))}" if sw.only else "") + ". The numbers are those of "
           "<code>sweep.csv</code>.</p>",
           f"<p class='legend'><span class='notok'>■</span> {e(_LEGEND[NOT_OK])}; "
           f"<span class='notmet'>■</span> {e(_LEGEND[NOT_MET])}.</p>",
           f"<img src='{PNG}' alt='each metric against the swept key'>",
           "<h2>Plotted metrics</h2><table><tr><th>metric</th><th>unit</th><th>min (ok points)</th>"
           "<th>max (ok points)</th></tr>"]
    ok_rows = classes != NOT_OK
    for j in plotted:
        y = data[ok_rows, j]
        y = y[np.isfinite(y)]
        lo, hi = (float(y.min()), float(y.max())) if y.size else (math.nan, math.nan)
        out.append(f"<tr data-metric='{e(cols[j])}'><td>{e(cols[j])}</td><td>{e(unit(cols[j]))}</td>"
                   f"<td class='n'>{_num(lo)}</td><td class='n'>{_num(hi)}</td></tr>")
    out.append("</table>")
    if constant:
        out.append("<p>Constant over the sweep (not plotted): " + ", ".join(
            f"{e(c)} = {_num(float(np.nanmax(data[:, cols.index(c)])))} {e(unit(c))}" for c in constant) + ".</p>")
    if empty:
        out.append("<p>No finite value at any point (not plotted): " + e(", ".join(empty)) + ".</p>")
    bad = [i for i, k in enumerate(classes) if k != OK]
    if bad:
        counts = Counter((int(classes[i]), reason(result.results[i])) for i in bad)
        out.append("<h2>Points that are not ok or not met, per reason</h2><table><tr><th>class</th><th>reason</th>"
                   "<th>points</th></tr>")
        for (k, why), count in counts.most_common():
            cls, word = ("notok", "not ok") if k == NOT_OK else ("notmet", "not met")
            out.append(f"<tr class='{cls}'><td>{word}</td><td>{e(why)}</td><td class='n'>{count}</td></tr>")
        out.append("</table>")
        listed = [i for i in bad if classes[i] == NOT_OK]
        if listed:
            out.append("<h2>Points that are not ok</h2><table><tr>" + "".join(f"<th>{e(a.label)}</th>" for a in sw.axes)
                       + "<th>outcome</th><th>message</th></tr>")
            for i in listed[:MAX_LISTED]:
                r = result.results[i]
                out.append("<tr>" + "".join(f"<td class='n'>{v:g}</td>" for v in result.points[i])
                           + f"<td>{e(str(r.outcome))}</td><td>{e(r.message[:300])}</td></tr>")
            out.append("</table>")
            if len(listed) > MAX_LISTED:
                out.append(f"<p>… and {len(listed) - MAX_LISTED} more (every point is in <code>sweep.csv</code> "
                           "and the record).</p>")
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def write(result: Any, header: Sequence[str], rows: Sequence[Sequence[Any]], out_dir: Path) -> list[Path]:
    """``overview.png`` and ``overview.html`` in ``out_dir`` from the sweep table (``header``, ``rows``)."""
    n_ax = len(result.sweep.axes)
    cols = list(header[n_ax + 1:])
    data = np.array([[float(v) for v in r[n_ax + 1:]] for r in rows], dtype=float).reshape(len(rows), len(cols))
    classes = np.array([point_class(r) for r in result.results], dtype=int)
    plotted, constant, empty = chosen(cols, data)
    left = [cols[j] for j in plotted[MAX_PANELS:]]  # named on the page
    plotted = plotted[:MAX_PANELS]
    out_dir = Path(out_dir)
    png, page = out_dir / PNG, out_dir / HTML
    write_png(result, cols, data, classes, plotted, png)
    text = html_page(result, cols, data, classes, plotted, constant, empty)
    if left:
        text = text.replace("</body>", f"<p>Past {MAX_PANELS} panels, not plotted: {html.escape(', '.join(left))}."
                                       "</p></body>")
    write_text(page, text)
    return [png, page]
