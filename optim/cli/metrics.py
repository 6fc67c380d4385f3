"""``hapticopt metrics [--device D] [--json]``: the metric glossary, generated from the registry.

Each evaluator entry of :mod:`hapticopt.analysis.registry` describes its metrics (one source of
truth); the unit comes from the metric name's suffix. ``docs/metrics.md`` is :func:`markdown`'s
output, written by ``scripts/gen_metrics_doc.py`` (``tests/optim/cli/test_metrics.py`` fails when
the file is stale).
"""

from __future__ import annotations

from typing import Annotated, Any, Optional

import typer

from hapticopt.optim import strict_json

from hapticopt.analysis.registry import ALL_LEVELS, EVALUATORS, glossary
from hapticopt.optim.cli import render
from hapticopt.optim.cli.common import one_line_errors

#: devices in the order the glossary lists them, with the seed each comes from
DEVICE_TITLES = {"prrr": "3-PRRR (seed 002)", "master": "PHANToM-type master (seed 003)",
                 "handle": "force-feedback handle (seed 000)"}


def _levels(row: dict[str, Any]) -> str:
    return "all" if len(row["fidelities"]) == len(ALL_LEVELS) else ", ".join(row["fidelities"])


def _sections(device: str | None) -> list[tuple[str, str, str, str, list[dict[str, Any]]]]:
    """(device, evaluator, module, fidelity note, rows) in report order."""
    rows = glossary(device)
    out = []
    for dev in ([device] if device else list(EVALUATORS)):
        for e in EVALUATORS[dev]:
            out.append((dev, e.name, e.module, e.fidelity,
                        [r for r in rows if r["device"] == dev and r["evaluator"] == e.name]))
    return out


def markdown() -> str:
    """docs/metrics.md: every device's metrics, one table per evaluator."""
    lines = ["# Metric glossary", "",
             "Generated from the evaluator entries of `analysis/registry.py` by `scripts/gen_metrics_doc.py`",
             "(`hapticopt metrics [--device D] [--json]` prints the same); do not edit by hand —",
             "`tests/optim/cli/test_metrics.py` fails when this file is stale.", "",
             "The unit is the metric name's suffix (`_N_per_mm` → N/mm, `_pct` → %; none: dimensionless).",
             "Vector metrics list their components in the order the description gives (x, y, z unless",
             "stated). *Levels* are the fidelity levels at which the evaluator reports the metric.", ""]
    current = None
    for dev, name, module, note, rows in _sections(None):
        if dev != current:
            lines += [f"## {dev} — {DEVICE_TITLES.get(dev, dev)}", ""]
            current = dev
        lines += [f"### {name} (`{module}`)", "", f"Fidelity: {note}.", "",
                  "| metric | unit | levels | meaning |", "|---|---|---|---|"]
        for r in rows:
            lines.append(f"| `{r['metric']}` | {r['unit'] or '-'} | {_levels(r)} | "
                         f"{r['description'].replace('|', '/')} |")
        lines.append("")
    return "\n".join(lines)


@one_line_errors
def metrics(
    device: Annotated[Optional[str], typer.Option("--device", help="prrr, master or handle [default: all].")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON list [{device, evaluator, module, metric, "
                                                         "unit, description, fidelities, fidelity_note}].")] = False,
) -> None:
    """List every metric: unit, meaning, fidelity levels, evaluator and device (the glossary)."""
    sections = _sections(device)  # checks --device
    if as_json:
        typer.echo(strict_json.dumps([r for *_, rows in sections for r in rows], indent=2, ensure_ascii=False))
        return
    console = render.console()
    for dev, name, module, note, rows in sections:
        console.print(render.table(f"{dev} · {name} ({module}) — fidelity: {note}",
                                   ("metric", "unit", "levels", "meaning"),
                                   ((r["metric"], r["unit"] or "-", _levels(r), r["description"]) for r in rows)))
