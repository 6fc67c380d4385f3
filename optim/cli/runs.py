"""``hapticopt runs [DIR]`` (list recorded runs) and ``hapticopt show RUN`` (one run's record).

Both read through :class:`hapticopt.optim.runs.RunReader`, which opens the record read-only.
"""

from __future__ import annotations

import csv
import io as _io
import math
import sqlite3
from pathlib import Path
from typing import Annotated, Any

import typer

from hapticopt.optim import strict_json
from rich.console import Console
from rich.table import Table

from hapticopt.design.errors import HapticoptError, InvalidInput
from hapticopt.optim.cli.common import one_line_errors
from hapticopt.optim.runs import RunReader, RunSummary, as_dict, failure_counts, find_runs


def _fmt(value: Any) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if value is None:
        return "—"
    if isinstance(value, float):
        return "—" if math.isnan(value) else f"{value:.6g}"
    return str(value)


@one_line_errors
def runs(
    directory: Annotated[Path, typer.Argument(help="Folder to search for run directories (3 levels deep).")] = Path("cad_out"),
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON list instead of a table.")] = False,
) -> None:
    """List recorded runs: problem, kind, status, evaluations, best objective, feasible."""
    if not directory.is_dir():
        raise InvalidInput(f"DIR = {str(directory)!r} is not a folder")
    summaries = []
    for run_dir in find_runs(directory):
        try:
            with RunReader(run_dir) as reader:
                summaries.append(reader.summary())
        except (HapticoptError, sqlite3.Error, OSError, ValueError, KeyError, TypeError) as exc:
            typer.echo(f"warning: skipped {run_dir}: {' '.join(str(exc).split())[:300]}", err=True)
    if as_json:
        typer.echo(strict_json.dumps([as_dict(s) for s in summaries], indent=2))
        return
    if not summaries:
        typer.echo(f"no runs under {directory}")
        return
    table = Table(title=f"runs under {directory}")
    for col in ("run", "problem", "kind", "status", "evals (failed)", "best objective (fidelity)", "feasible"):
        table.add_column(col, overflow="fold")
    for s in summaries:
        rel = s.path.relative_to(directory) if s.path != directory else Path(".")
        table.add_row(str(rel), s.problem, s.kind, s.status, f"{s.n_evaluations} ({s.n_failed})", _best(s),
                      _fmt(s.feasible))
    Console().print(table)


def _best(s: RunSummary) -> str:
    """The best value with the fidelity it holds at, and the final design's value at its own fidelity."""
    if math.isnan(s.best):
        return "—"
    text = f"{_fmt(s.best)} ({s.best_fidelity or '?'})"
    if s.final_fidelity and s.final_fidelity != s.best_fidelity:
        text += f"; final {_fmt(s.final)} ({s.final_fidelity})"
    return text


@one_line_errors
def show(
    run: Annotated[Path, typer.Argument(help="Run directory (or its evaluations.sqlite).", show_default=False)],
    as_json: Annotated[bool, typer.Option("--json", help="Print the whole record as JSON.")] = False,
    as_csv: Annotated[bool, typer.Option("--csv", help="Print the history as CSV (one row per evaluation).")] = False,
    last: Annotated[int, typer.Option("--last", help="History rows shown in the table (the JSON and CSV have all).")] = 15,
) -> None:
    """Show one run: what it optimised, its sessions, its best design and its history."""
    if as_json and as_csv:
        raise InvalidInput("give at most one of --json and --csv")
    if last < 0:
        raise InvalidInput(f"--last = {last} must be ≥ 0 (rows)")
    with RunReader(run) as reader:
        cols, rows = reader.history_table()
        best = reader.best()
        if as_csv:
            buf = _io.StringIO()
            w = csv.writer(buf, lineterminator="\n")
            w.writerow(cols)
            w.writerows([[("" if isinstance(v, float) and math.isnan(v) else v) for v in r] for r in rows])
            typer.echo(buf.getvalue(), nl=False)
            return
        summary = reader.summary()
        designs = reader.designs()
        failed = reader.failures()
        if as_json:
            payload = {
                **as_dict(summary),
                "info": {k: v for k, v in reader.info.items()},
                "sessions": reader.sessions(),
                "best_case": None if best is None else {"id": best.id, "x": list(best.x),
                                                   "objectives": list(reader.objective_values(best)),
                                                   "feasible": reader.feasible(best)},
                "designs": [{"role": d.role, "fidelity": d.fidelity, "x": list(d.x), "metrics": d.metrics,
                             "statuses": d.statuses} for d in designs],
                "history": {"columns": cols, "rows": rows},
                "failures": {"count_by_reason": failure_counts(failed),
                             "evaluations": [{"id": c.id, "outcome": c.outcome, "message": c.message,
                                              "fidelity": c.fidelity,
                                              "statuses": {k: v for k, v in c.statuses.items() if v != "ok"}}
                                             for c in failed]},
            }
            typer.echo(strict_json.dumps(payload, indent=2))
            return
        console = Console()
        console.print(f"[bold]{summary.problem}[/bold] ({summary.kind}, {summary.status}): {summary.n_evaluations} "
                      f"evaluations, {summary.repeated} repeated — {reader.path}")
        for s in reader.sessions():
            extra = (f", budget {s['max_evals']}, {s['evaluated']} evaluated, {s['replayed']} replayed, "
                     f"{s['repeated']} repeated" if s.get("evaluated") is not None else "")
            console.print(f"  session {s['session']}{' (resumed)' if s['resumed'] else ''}: {s['recorded']} recorded{extra}")
        variables = reader.variables or []
        if best is not None:
            objs = ", ".join(f"{o['metric']} ({o['sense']}) = {_fmt(v)}"
                             for o, v in zip(reader.objectives or [], reader.objective_values(best)))
            which = "best by the first objective" if len(reader.objectives or []) > 1 else "best"
            console.print(f"{which}: evaluation {best.id} at {best.fidelity} fidelity, {objs}, feasible "
                          f"{_fmt(reader.feasible(best))}")
            if summary.final_fidelity:
                console.print(f"final design (the optimum re-evaluated) at {summary.final_fidelity} fidelity: "
                              f"{(reader.objectives or [{}])[0].get('metric', '')} = {_fmt(summary.final)}")
            table = Table(title="best design")
            for col in ("variable", "unit", "lower", "upper", "start", "best"):
                table.add_column(col)
            for v, x in zip(variables, best.x):
                table.add_row(v["key"], v["unit"], _fmt(v["lower"]), _fmt(v["upper"]), _fmt(v["start"]), _fmt(x))
            console.print(table)
        if designs:
            groups: dict[tuple[str, str, int], int] = {}
            for d in designs:
                groups[(d.role, d.fidelity, d.session)] = groups.get((d.role, d.fidelity, d.session), 0) + 1
            console.print("recorded designs: " + ", ".join(
                f"{'' if n == 1 else f'{n} × '}{role} ({fid}, session {ses})" for (role, fid, ses), n in groups.items()))
        chosen = reader.design("chosen")
        if reader.kind == "pareto" and chosen is not None:
            vals = ", ".join(f"{o['metric']} = {_fmt(v)}"
                             for o, v in zip(reader.objectives or [], reader.objective_values(chosen)))
            n_front = sum(d.role == "front" and d.session == chosen.session for d in designs)
            console.print(f"Pareto front: {n_front} points; chosen design at {chosen.fidelity} fidelity: {vals}")
        if failed:
            console.print(f"failed evaluations: {len(failed)} of {summary.n_evaluations}; by reason:")
            for reason, n in failure_counts(failed).items():
                console.print(f"  {n} × {reason}")
            for c in failed[-min(len(failed), 5):]:
                console.print(f"  evaluation {c.id} ({c.fidelity}): {c.outcome}: {c.message}", soft_wrap=False)
            if len(failed) > 5:
                console.print(f"  … {len(failed) - 5} more (--json has every message)")
        shown = [i for i, c in enumerate(cols) if c not in ("session", "start", "stage")]  # in --csv/--json
        table = Table(title=f"history (last {min(last, len(rows))} of {len(rows)}; --csv for all)")
        for i in shown:
            table.add_column(cols[i], overflow="fold")
        for r in rows[len(rows) - last:] if last else []:
            table.add_row(*(_fmt(r[i]) for i in shown))
        console.print(table)
