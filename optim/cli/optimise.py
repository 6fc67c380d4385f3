"""``hapticopt optimise PROBLEM`` and ``hapticopt problems``."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Annotated, Optional

import typer

from hapticopt.optim import strict_json

from hapticopt.optim.cli.common import (
    CACHE_HELP, MAX_WORKERS, NO_CACHE_HELP, ComputeOption, ThreadsOption, cache_file, not_met, one_line_errors,
    parse_compute, stage_failed,
)
from hapticopt.design.errors import InvalidInput
from hapticopt.optim.problem import INT_RANGES, load_problem
from hapticopt.optim.cli import render
from hapticopt.optim.cli.progress import StageLine, make_progress
from hapticopt.optim.problem import problem_names
from hapticopt.optim.recorder import check_run_dir
from hapticopt.optim.runs import RunReader



def remove_fresh_run(out_dir: Path, *, keep_folder: bool) -> None:
    """Remove what a run rejected after its baseline wrote into a folder that held nothing of a run
    (the folder itself unless it existed before)."""
    for child in out_dir.iterdir():
        if child.is_dir() and not child.is_symlink():
            shutil.rmtree(child)
        else:
            child.unlink()
    if not keep_folder:
        out_dir.rmdir()


def previous_budget(out_dir: Path) -> tuple[int, int] | None:
    """(budget of the last recorded session, evaluations recorded) of the run in ``out_dir``, or None
    (no record, or a record without session counts)."""
    try:
        with RunReader(out_dir) as reader:
            sessions = [s for s in reader.sessions() if s.get("max_evals") is not None]
            recorded = len(reader)
    except Exception:  # noqa: BLE001 - no readable record: the resume itself says why
        return None
    return (int(sessions[-1]["max_evals"]), recorded) if sessions else None


def resume_note(cfg, previous: tuple[int, int], result) -> str:
    """The one line a resume that evaluated nothing prints: whether the budget was extended and why the
    optimiser still stopped where it had (its starts' stop reasons), and whether the export was kept."""
    budget, recorded = previous
    stops = ", ".join(f"start {s.start}: {s.status}" for s in result.run.starts) or "no start ran"
    kept = any(s.name == "export" and "kept" in s.message for s in result.stages)
    tail = "; the optimum did not change, its export was kept" if kept else ""
    if cfg.max_evals > budget:
        return (f"resume: 0 new evaluations: the recorded run had stopped on its own before its budget of {budget} "
                f"({stops}; xtol_rel {cfg.xtol_rel:g}, ftol_rel {cfg.ftol_rel:g}), and replaying it stops at the same "
                f"point, so --max-evals {cfg.max_evals} adds nothing; tighten xtol_rel/ftol_rel or add starts in the "
                f"problem (a new run) to search further{tail}")
    return (f"resume: the run had already finished with its budget of {budget} ({recorded} evaluations recorded, "
            f"{stops}): nothing new to evaluate; give --max-evals above {budget} to extend it{tail}")


@one_line_errors
def optimise(
    problem: Annotated[str, typer.Argument(help="Bundled problem name (see `hapticopt problems`) or a problem TOML file.",
                                           show_default=False)],
    out: Annotated[Optional[Path], typer.Option("--out", help="Run directory (default cad_out/<problem-name>/).")] = None,
    resume: Annotated[bool, typer.Option("--resume", help="Continue the run in --out: recorded evaluations are replayed, not recomputed (with --max-evals: extend its budget).")] = False,
    force: Annotated[bool, typer.Option("--force", help="Replace the run already recorded in --out (without it, an existing run is refused).")] = False,
    max_evals: Annotated[Optional[int], typer.Option("--max-evals", help="Total evaluation budget (overrides the problem's).")] = None,
    scheduler: Annotated[str, typer.Option("--scheduler", help="local (process pool), inline, or a Dask scheduler address tcp://HOST:PORT.")] = "local",
    workers: Annotated[Optional[int], typer.Option("--workers", help="Processes of the local pool (default: min(4, CPUs)).")] = None,
    export: Annotated[bool, typer.Option("--export/--no-export", help="Export STEP/STL/MJCF of the optimum.")] = True,
    verify: Annotated[bool, typer.Option("--verify/--no-verify", help="Verify the optimum in closed loop on the problem's scenes.")] = True,
    quiet: Annotated[bool, typer.Option("--quiet", help="No progress display.")] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print the run's result.json (instead of the summary lines).")] = False,
    cache: Annotated[Optional[Path], typer.Option("--cache", help=CACHE_HELP.replace("DIR", "OUT"))] = None,
    no_cache: Annotated[bool, typer.Option("--no-cache", help=NO_CACHE_HELP)] = False,
    compute: ComputeOption = "auto",
    threads: ThreadsOption = None,
) -> None:
    """Optimise a design problem, re-evaluate the optimum at fine fidelity, export, verify, report (two objectives: a Pareto front). Exit 3 when the final point breaks a constraint (written as best_infeasible.toml) or a verification scene does not pass; exit 5 when the export or a plot failed."""

    route = parse_compute(compute, threads)
    prob = load_problem(problem)
    if max_evals is not None:
        lo, hi = INT_RANGES["max_evals"]
        if not lo <= max_evals <= hi:
            raise InvalidInput(f"--max-evals = {max_evals} is out of range: allowed {lo} ≤ --max-evals ≤ {hi}")
        if max_evals < prob.optimiser.starts:
            raise InvalidInput(f"--max-evals = {max_evals} must be at least the number of starts ({prob.optimiser.starts})")
        prob = prob.with_optimiser(max_evals=max_evals)
    if workers is not None and not 1 <= workers <= MAX_WORKERS:
        raise InvalidInput(f"--workers = {workers} is out of range: allowed 1 ≤ --workers ≤ {MAX_WORKERS}")
    out_dir = out if out is not None else Path("cad_out") / prob.name
    check_run_dir(out_dir, resume=resume, force=force)  # before anything is computed or written
    previous = previous_budget(out_dir) if resume else None
    cache_path = cache_file(cache, no_cache, out_dir)

    from hapticopt.optim.pipeline import ProblemRejected, run_front_pipeline, run_pipeline, status_holds

    console = render.console(stderr=True, quiet=quiet)
    if prob.is_multi_objective:
        with make_progress(console, disable=quiet) as bar:
            runs = prob.pareto.points if prob.pareto else 1
            line = StageLine(bar, "front", runs)
            line.note(f"ε-constraint runs at {prob.fidelity_optimise} fidelity, then the chosen design at "
                      f"{prob.fidelity_final}")
            done = [0]

            def on_run(label, n):
                done[0] += 1
                line.count(min(done[0], runs))
                line.note(f"run {label} done, {n} evaluated")

            res = run_front_pipeline(prob, out_dir=out_dir, resume=resume, force=force, scheduler=scheduler,
                                     workers=workers, cache=cache_path, progress=on_run, compute=route)
        ch = res["chosen"]
        if as_json:
            typer.echo(strict_json.dumps(res, indent=2))
        else:
            f1, f2 = (o["metric"] for o in res["objectives"])
            typer.echo(f"{prob.name}: Pareto front of {f1} and {f2}: {len(res['front'])} points "
                       f"(ε-constraint, {len(res['runs'])} runs); {res['n_evaluated']} evaluated, {res['n_replayed']} replayed")
            if ch is not None:
                typer.echo(f"  chosen ({prob.pareto.choose if prob.pareto else 'knee'}): {f1} = {ch['objectives'][0]:.6g}, "
                           f"{f2} = {ch['objectives'][1]:.6g}; constraints at {prob.fidelity_final} fidelity "
                           f"{'satisfied' if ch['feasible_at_final_fidelity'] else 'NOT satisfied'} -> "
                           f"{out_dir / (res['files'].get('chosen') or res['files']['chosen_infeasible'])}")
            if export or verify:
                typer.echo("  export/verify: not run for a Pareto front — run `hapticopt export` / `hapticopt verify` "
                           "on chosen.toml")
            typer.echo(f"report: {out_dir / 'report.html'}")
        if ch is not None and not ch["feasible_at_final_fidelity"]:
            not_met(f"the chosen design breaks a constraint at {prob.fidelity_final} fidelity "
                    f"(written as {out_dir / 'chosen_infeasible.toml'})")
        return
    with make_progress(console, disable=quiet) as bar:
        line = StageLine(bar, "baseline")

        def on_point(rec, best, n_evaluated):  # called from the driver (any thread)
            if best is None:
                desc = "no valid point yet"
            else:
                obj = best.objective
                feas = "feasible" if best.max_violation <= prob.optimiser.constraint_tol else \
                    f"infeasible (violation {100 * best.max_violation:.2g} %)"
                desc = f"best {prob.objective.metric.text} = {obj:.6g} ({feas})"
            line.count(min(rec.index + 1, prob.optimiser.max_evals))
            line.note(desc)

        def on_stage(name):
            totals = {"optimise": prob.optimiser.max_evals}
            texts = {"baseline": f"start design at {prob.fidelity_optimise}"
                                 + ("" if prob.fidelity_final == prob.fidelity_optimise
                                    else f" and {prob.fidelity_final}") + " fidelity",
                     "optimise": f"{prob.optimiser.algorithm} at {prob.fidelity_optimise} fidelity",
                     "final": f"optimum at {prob.fidelity_final} fidelity", "plots": "evaluator pictures",
                     "export": "STEP, STL, MJCF, render", "verify": "closed loop in the problem's scenes",
                     "report": "report.html, result.json"}
            line.stage(name, totals.get(name, 1), texts.get(name, ""))

        existed = out_dir.exists()
        fresh = not existed or (out_dir.is_dir() and not any(out_dir.iterdir()))  # nothing of a run there before
        try:
            result = run_pipeline(prob, out_dir=out_dir, resume=resume, force=force, scheduler=scheduler,
                                  workers=workers, progress=on_point, export=export, verify=verify, on_stage=on_stage,
                                  on_step=line.step, cache=cache_path, compute=route)
        except ProblemRejected:
            if fresh:  # bad input leaves no partial files: the corrected rerun needs no --force
                remove_fresh_run(out_dir, keep_folder=existed)
            raise
        line.stage("done", 1, f"{out_dir / 'report.html'}")
        line.count(1)
    if previous is not None and result.run.n_evaluated == 0:  # one line: why a resume added nothing
        typer.echo(resume_note(prob.optimiser, previous, result), err=True)
    if as_json:  # the exit code below still says whether the requirement holds
        typer.echo((out_dir / "result.json").read_text(encoding="utf-8"), nl=False)
    else:
        obj = prob.objective.metric
        b, o = obj.value(result.baseline.metrics), obj.value(result.optimum.metrics)
        typer.echo(f"{prob.name}: {result.run.status}; {obj.text} baseline {b:.6g} -> optimum {o:.6g} "
                   f"({'improved' if result.improved else 'not improved'}); constraints at {prob.fidelity_final} fidelity "
                   f"{'satisfied' if result.feasible_final else 'NOT satisfied'}; "
                   f"{result.run.n_evaluated} evaluated, {result.run.n_replayed} replayed")
        for s in result.stages:
            if s.name == "baseline" and s.message:
                typer.echo(f"  baseline: {s.message}")
        for v in result.verdicts:
            typer.echo(f"  verify {v.scene}: {'PASS' if v.passed else 'FAIL'} {v.message}")
        for s in result.stages:
            if s.status in ("skipped", "failed"):
                typer.echo(f"  {s.name}: {s.status} — {s.message}")
        typer.echo(f"report: {out_dir / 'report.html'}")
    failed = [s for s in result.stages if s.status == "failed"]
    if failed:  # exit 5: an output the run promised is missing
        stage_failed("; ".join(f"{s.name} failed: {s.message}" for s in failed) + f" (the rest of the run is in {out_dir})")
    broken_lines = [f"verify {v.scene}: FAIL {v.message}" for v in result.verdicts if not v.passed]
    if not result.feasible_final:
        broken = [t for t, _, ok in result.constraints_final if not ok]
        bad = [f"{k} ({s})" for k, s in result.optimum.statuses.items() if not status_holds(s)]
        broken_lines.insert(0, f"the final point is infeasible at {prob.fidelity_final} fidelity: "
                            + ", ".join(broken + bad) + f" (written as {out_dir / 'best_infeasible.toml'}, not optimum.toml)")
    if broken_lines:
        not_met("; ".join(broken_lines))


@one_line_errors
def problems(
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON list [{name, device, description, objectives, "
                                                         "variables}].")] = False,
) -> None:
    """List the bundled optimisation problems."""
    rows = []
    for name in problem_names():
        p = load_problem(name)
        objectives = [o.metric.text for o in p.objectives] if p.is_multi_objective else [p.objective.metric.text]
        rows.append({"name": name, "device": p.device, "description": p.description, "objectives": objectives,
                     "variables": [v.key for v in p.variables]})
    if as_json:
        typer.echo(strict_json.dumps(rows, indent=2, ensure_ascii=False))
        return
    render.console().print(render.table(None, ("problem", "device", "description"),
                                        ((r["name"], r["device"], r["description"]) for r in rows)))
