"""``hapticopt compare A B …``: designs (files, presets or run directories) side by side."""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Annotated, Optional

import typer

from hapticopt.optim import strict_json
from rich.console import Console
from rich.table import Table
from rich.text import Text

from hapticopt.design.errors import InvalidInput
from hapticopt.design.paths import output_root, writable_dir
from hapticopt.optim.cache import EvaluationCache
from hapticopt.optim.recorder import run_lock
from hapticopt.optim.cli.common import CACHE_HELP, NO_CACHE_HELP, cache_file, one_line_errors, parse_fidelity


#: terminal style of a delta by its verdict
_STYLE = {"better": "green", "worse": "red", "changed": "dim"}


@one_line_errors
def compare(
    designs: Annotated[list[str], typer.Argument(help="Two or more designs: design TOML files, preset names or run "
                                                      "directories (their optimum). The first is the reference.",
                                                 show_default=False)],
    fidelity: Annotated[str, typer.Option("--fidelity", help="draft, standard or fine (one level for all).")] = "standard",
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON {designs, metrics, design_differences}.")] = False,
    report: Annotated[Optional[Path], typer.Option("--report", help="Also write the comparison to FILE.md or FILE.html.")] = None,
    renders: Annotated[bool, typer.Option("--renders", help="With --report: a picture of each design (CAD export; seconds per design).")] = False,
    changed_only: Annotated[bool, typer.Option("--changed-only", help="Table: only metrics that differ.")] = False,
    cache: Annotated[Optional[Path], typer.Option("--cache", help=CACHE_HELP.replace(
        "DIR/", "the first run directory among the designs, if any: RUN/"))] = None,
    no_cache: Annotated[bool, typer.Option("--no-cache", help=NO_CACHE_HELP)] = False,
) -> None:
    """Evaluate designs at one fidelity and show every metric side by side with deltas, units and statuses."""
    from hapticopt.optim import compare as cmp  # heavy (evaluators, jax): imported when the command runs

    level = parse_fidelity(fidelity)
    if len(designs) < 2:
        raise InvalidInput(f"compare needs at least 2 designs, got {len(designs)}")
    if renders and report is None:
        raise InvalidInput("--renders needs --report FILE.md or FILE.html")
    if report is not None and report.suffix not in (".md", ".html"):
        raise InvalidInput(f"--report = {str(report)!r} must end in .md or .html")
    named = [cmp.resolve(d) for d in designs]
    run_dirs = [Path(d) for d in designs if Path(d).is_dir()]
    cache_path = cache_file(cache, no_cache, run_dirs[0] if run_dirs else None)
    with EvaluationCache(cache_path) if cache_path is not None else contextlib.nullcontext() as ecache:
        result = cmp.compare(named, fidelity=level, cache=ecache)
    written: list[Path] = []
    if report is not None:  # one writer of the report's folder at a time; no write follows a link there
        folder = writable_dir(report.parent if str(report.parent) else Path("."), "--report")
        with output_root(folder), run_lock(folder):
            written = cmp.write_report(result, report, renders=renders)
    if as_json:
        typer.echo(strict_json.dumps(cmp.as_json(result), indent=2))
        return
    console = Console()
    labels = [d.label for d in named]
    table = Table(title=f"{' vs '.join(labels)} ({level} fidelity; Δ from {labels[0]}, relative; "
                        "--json has absolute deltas)")
    table.add_column("metric", overflow="fold")
    table.add_column("unit")
    table.add_column(labels[0], justify="right", overflow="fold")
    for b in labels[1:]:
        table.add_column(b, justify="right", overflow="fold")
        table.add_column(f"Δ {b}", justify="right", overflow="fold")
    for r in result.rows:
        if changed_only and all(v == "same" for v in r.verdicts[1:]):
            continue
        cells: list[str | Text] = [cmp.fmt(r.values[0])]
        for i in range(1, len(labels)):
            v = cmp.verdict(r, i)
            cells += [cmp.fmt(r.values[i]), Text(cmp.fmt_short(r.deltas[i], r.relative[i], v == "same")
                                                 + (f" {cmp.MARKS[v][0]}" if cmp.MARKS[v] else ""), style=_STYLE.get(v, ""))]
        table.add_row(r.metric, r.unit, *cells)
    console.print(table)
    console.print(cmp.LEGEND.replace("green better, red worse", "▲ green better, ▼ red worse"))
    for d, st, msg, prov in zip(named, result.statuses, result.messages, result.provenance):
        bad = {k: v for k, v in st.items() if v != "ok"}
        line = "all evaluators ok" if not bad else "; ".join(f"{k}: {v}" + (f" — {msg[k]}" if k in msg else "")
                                                             for k, v in bad.items())
        console.print(f"{d.label} ({d.source}): {line}" + (f"; values {prov}" if prov else ""))
    for path in written[:1]:
        console.print(f"wrote {path}")
