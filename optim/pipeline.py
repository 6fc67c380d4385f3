"""The whole job: optimise → re-evaluate the best at fine fidelity → export → verify → report.

``run_pipeline(problem, out_dir=…)`` writes into ``out_dir``: ``evaluations.sqlite`` (the
recorder), ``optimum.toml`` (the optimised design, when it is feasible at the final fidelity:
every constraint holds and every evaluator's numbers hold, :func:`holds`; otherwise the best
point is written as ``best_infeasible.toml`` and no ``optimum.toml`` exists), ``result.json``, the export files
(STEP/STL/MJCF/PNG from :mod:`hapticopt.design.export`), evaluator and verification pictures
under ``plots/``, ``convergence.svg``, ``report.md`` and ``report.html``. Stage wall times are
measured and reported; a stage that fails is reported with its reason, never silently.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, Future
from pathlib import Path
from typing import Any

from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.design import io
from hapticopt.design.atomic import write_text
from hapticopt.optim.driver import EvalRecord, ProgressFn
from hapticopt.design.errors import InvalidInput, UnknownName
from hapticopt.optim.problem import Problem, check_metrics
from hapticopt.analysis.registry import EVALUATORS, describe_failure, jsonable, run_plotter
from hapticopt.design.paths import inside
from hapticopt.optim.driver import SMOOTH_SURROGATES
from hapticopt.analysis.loop import mujoco_compiled
from hapticopt.analysis.loop.scene import load_scene
from hapticopt.optim.reaper import children_die_with_this_process
from hapticopt.optim.recorder import Recorder, check_run_dir, run_lock
from hapticopt.optim.runs import problem_info
from hapticopt.design.atomic import file_set, remove_stale_temp_files
from hapticopt.design.paths import make_dirs, no_links, output_root, writable_dir
from hapticopt.optim.executor import InlineExecutor, check_scheduler, make_executor, worker_compute
from hapticopt.optim import side as side_process
from hapticopt.optim.side import side_executor
from hapticopt.optim.worker import SupervisedWorker
from hapticopt.optim import driver, pareto, pareto_report, report, strict_json
from hapticopt.optim.results import DesignEvaluation, PipelineResult, StageOutcome, TimeHistory, Verdict
from hapticopt.analysis import verify as closed_loop_verify
from hapticopt.optim import cache as evaluation_cache
from hapticopt.optim.cache import CachedEvaluation, EvaluationCache


#: ``on_step(what, done, total)``: progress inside a stage (an evaluator, an export step, a scene)
StepFn = Callable[[str, int, int], None]


def evaluate_design(design: Any, fidelity: Fidelity, on_step: StepFn | None = None, *,
                    cache: EvaluationCache | None = None, reuse: bool = True,
                    compute: Compute = DEFAULT) -> DesignEvaluation:
    """Every registered evaluator on ``design`` (the registry's one loop and failure policy),
    through the evaluation ``cache`` when one is given (:func:`hapticopt.optim.cache.evaluate`)."""
    ev = evaluation_cache.evaluate(design, fidelity, cache=cache, reuse=reuse, written_by="hapticopt optimise",
                                   progress=on_step, compute=compute)
    return DesignEvaluation(fidelity=fidelity, metrics=ev.metrics, modules=ev.modules, statuses=ev.statuses,
                            messages=ev.messages, timings_s=ev.timings_s, results=ev.results,
                            provenance=ev.provenance)


#: the design file of a run's result, feasible or not (single objective; a Pareto front's choice)
OPTIMUM_FILE, INFEASIBLE_FILE = "optimum.toml", "best_infeasible.toml"
CHOSEN_FILE, CHOSEN_INFEASIBLE_FILE = "chosen.toml", "chosen_infeasible.toml"


def holds(constraints: tuple[tuple[str, float, bool], ...], statuses: dict[str, str]) -> bool:
    """Whether a final point is feasible: every constraint holds, and every evaluator's numbers
    hold (:attr:`Status.metrics_hold`: a ``not-met`` or ``collides`` of an evaluator the problem does
    not constrain is reported, not counted; ``failed``, ``singular``, ``not-assemblable`` … are)."""
    return all(ok for _, _, ok in constraints) and all(status_holds(s) for s in statuses.values())


def status_holds(word: str) -> bool:
    """Whether an evaluator status word of a record means its numbers hold (unknown words: no)."""
    try:
        return Status.parse(word).metrics_hold
    except ValueError:  # a word this version does not know is not a number to trust
        return False


def evaluators_for(problem: Problem, evaluation: DesignEvaluation) -> tuple[str, ...]:
    """Names of the evaluators that produce the problem's metrics (the only ones run per point)."""

    needed_modules = {evaluation.modules[r.name] for r in problem.metric_refs() if r.name in evaluation.modules}

    for r in problem.metric_refs():
        sur = SMOOTH_SURROGATES.get(r.name)
        if sur in evaluation.modules:
            needed_modules.add(evaluation.modules[sur])
    return tuple(e.name for e in EVALUATORS[problem.device] if e.module in needed_modules)


# ------------------------------------------------------------------------------ stages
#: verdict rule where a scene renders a spring: rendered-stiffness error bound (issue 6's acceptance, 10 %)
STIFFNESS_ERROR_LIMIT_PCT = 10.0


def run_scene(design: Any, scene: str, fidelity: Fidelity, compute: Compute = DEFAULT) -> Any:
    """The closed-loop verification of ``design`` in the bundled or file scene ``scene``."""
    return closed_loop_verify.simulate(design, load_scene(scene), fidelity=fidelity, compute=compute)


def verdict_of(metrics: dict[str, Any]) -> tuple[bool, str]:
    """PASS = stable, and the rendered-stiffness error ≤ :data:`STIFFNESS_ERROR_LIMIT_PCT` where measured."""
    if not metrics.get("stable", False):
        return False, "unstable"
    err = metrics.get("stiffness_error_pct")
    if isinstance(err, (int, float)) and err > STIFFNESS_ERROR_LIMIT_PCT:
        return False, f"rendered stiffness error {err:.3g} % > {STIFFNESS_ERROR_LIMIT_PCT:g} %"
    return True, "stable" + (f", stiffness error {err:.3g} %" if isinstance(err, (int, float)) else "")


def _scene_task(design: Any, scene: str, fidelity: Fidelity, verifier: Any, compute: Compute = DEFAULT
                ) -> tuple[dict[str, Any], str, TimeHistory | None]:
    """In the verification worker: one scene → (metrics, message, time history for the report)."""
    result = verifier(design, scene) if verifier is not None else run_scene(design, scene, fidelity, compute)
    history = TimeHistory.from_traces(getattr(result, "traces", None))
    return jsonable(result.metrics()), str(getattr(result, "message", "")), history


def warm_verification(compiled_loops: bool = False) -> None:
    """In the verification worker, once at its start: the imports (this module's) and jax's runtime; with
    ``compiled_loops`` also the compiled MuJoCo loops (the numba import and cache load, or a first compile:
    seconds, docs/performance.md)."""
    from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
    import jax.numpy as jnp

    jnp.zeros(1).block_until_ready()
    if compiled_loops:
        from hapticopt.analysis.prrr.loop import mujoco_plant as prrr_mujoco  # jax, numba

        prrr_mujoco.warm_up()  # unavailable: the plants run their Python loops and say why


def verification_worker(scenes: Sequence[str] = ()) -> SupervisedWorker:
    """The one process the verify stage runs its scenes in (:mod:`hapticopt.optim.worker`); it warms the compiled
    MuJoCo loops at start when one of ``scenes`` runs on a MuJoCo plant."""
    if mujoco_compiled.needed_by(scenes):
        return SupervisedWorker(warm=functools.partial(warm_verification, True))
    return SupervisedWorker(warm=warm_verification)


def _verify(design: Any, scenes: tuple[str, ...], out_dir: Path, fidelity: Fidelity, max_time_s: float,
            verifier: Callable[[Any, str], Any] | None = None, worker: SupervisedWorker | None = None,
            on_step: StepFn | None = None, compute: Compute = DEFAULT) -> tuple[StageOutcome, tuple[Verdict, ...]]:
    """Each scene in turn in one long-lived child process (``worker``, started here if not given),
    ``max_time_s`` each: a scene that hangs is killed there, one that crashes the process (a segfault,
    the OOM killer) fails its verdict, and the next scene gets a fresh process."""
    t0 = time.perf_counter()
    if not scenes:
        return StageOutcome(name="verify", status="skipped", message="the problem names no scenes"), ()
    own = worker is None
    worker = verification_worker() if worker is None else worker
    verdicts = []
    try:
        for k, scene in enumerate(scenes):
            if on_step is not None:
                on_step(scene, k, len(scenes))
            o = worker.call(_scene_task, (design, scene, fidelity, verifier, compute), timeout_s=max_time_s)
            history = None
            if o.kind == "ok":
                metrics, message, history = o.value
                passed, why = verdict_of(metrics)
                message = "; ".join(m for m in (why, message) if m)
            else:
                metrics, passed = {}, False
                message = (f"no result within {max_time_s:g} s (verify.max_time_s): the simulation was stopped"
                           if o.kind == "timeout" else o.message)
            verdicts.append(Verdict(scene=scene, passed=passed, metrics=metrics, message=message, history=history))
        if on_step is not None:
            on_step("", len(scenes), len(scenes))
    finally:
        if own:
            worker.close()
    n_pass = sum(v.passed for v in verdicts)
    return (StageOutcome(name="verify", status=f"{n_pass}/{len(verdicts)} passed", wall_s=time.perf_counter() - t0),
            tuple(verdicts))


def _constraints_at(problem: Problem, metrics: dict[str, Any]) -> tuple[tuple[str, float, bool], ...]:
    out = []
    tol = problem.optimiser.constraint_tol
    for c in problem.constraints:
        v = c.metric.value(metrics)
        out.append((c.text, v, math.isfinite(v) and c.normalised(v) <= tol))
    return tuple(out)


def run_pipeline(problem: Problem, *, out_dir: str | Path, resume: bool = False, force: bool = False,
                 scheduler: str = "local",
                 workers: int | None = None, progress: ProgressFn | None = None, export: bool = True,
                 verify: bool = True, on_stage: Callable[[str], None] | None = None,
                 verifier: Callable[[Any, str], Any] | None = None, on_step: StepFn | None = None,
                 cache: str | Path | None = None, compute: Compute = DEFAULT) -> PipelineResult:
    """Run every stage; returns the result and writes the run directory. ``compute`` is the route of every
    evaluation and simulation (one kernel thread in a worker process of a pool: :func:`worker_compute`).

    ``on_stage(name)`` is called as each stage starts (baseline, optimise, final, plots, export,
    verify, report); ``on_step(what, done, total)`` inside the stages that have steps (baseline and
    final: the evaluators, labelled ``fidelity: evaluator``; export: its steps; verify: the scenes).
    ``progress`` reports the optimiser's evaluations.

    ``verifier(design, scene_name) -> result with .metrics()`` replaces the closed-loop runner
    :func:`run_scene` (a module-level function: it runs in the verification child process). An existing record
    in ``out_dir`` is continued with ``resume``, replaced with ``force``, and otherwise refused.
    ``cache`` is the evaluation cache file (:mod:`hapticopt.optim.cache`; None: no cache): the base
    design's evaluations are served from it when there, and the optimum's final evaluation is stored.
    """
    check_run_dir(out_dir, resume=resume, force=force)

    # cheap checks first: a writable --out, the run lock, a reachable scheduler, then the baseline
    check_scheduler(scheduler)
    out = writable_dir(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with output_root(out), run_lock(out), children_die_with_this_process(), \
            verification_worker(problem.scenes if verify else ()) as verify_worker, side_executor(scheduler) as side:
        remove_stale_temp_files(out)
        for name in (OPTIMUM_FILE, INFEASIBLE_FILE, "plots", "parts", "result.json", "report.md", "report.html",
                     "convergence.svg"):  # a link planted where the run writes: refused before any work
            no_links(out / name, out)
        if verify and problem.scenes:
            verify_worker.start()  # now: its imports overlap with the optimisation, not the verify stage
        return _run_locked(problem, out, resume=resume, force=force, scheduler=scheduler, workers=workers,
                           progress=progress,
                           export=export, verify=verify, on_stage=on_stage, verifier=verifier, on_step=on_step,
                           verify_worker=verify_worker, cache=cache, side=side, compute=compute)


def _baseline_payload(ev: DesignEvaluation) -> dict[str, Any]:
    return {"fidelity": str(ev.fidelity), "metrics": jsonable(ev.metrics), "modules": ev.modules,
            "statuses": ev.statuses, "messages": ev.messages, "timings_s": ev.timings_s,
            "provenance": ev.provenance}


def _baseline_from(payload: dict[str, Any]) -> DesignEvaluation:
    return DesignEvaluation(fidelity=Fidelity(payload["fidelity"]), metrics=payload["metrics"],
                            modules=payload["modules"], statuses=payload["statuses"], messages=payload["messages"],
                            timings_s=payload["timings_s"], provenance=payload.get("provenance", ""))


def _replayed(rec: Recorder, key: str) -> DesignEvaluation | None:
    """The evaluation recorded under ``key`` by an earlier session of the run, or None."""
    found = rec.lookup_stage(key)
    if found is None:
        return None
    first = found.get("provenance")
    return dataclasses.replace(_baseline_from(found), provenance="replayed from the run record"
                               + (f" (it came {first})" if first else ""))


def _design_evaluation(ev: CachedEvaluation) -> DesignEvaluation:
    return DesignEvaluation(fidelity=ev.fidelity, metrics=ev.metrics, modules=ev.modules, statuses=ev.statuses,
                            messages=ev.messages, timings_s=ev.timings_s, results=ev.results,
                            provenance=ev.provenance)


def _recorded_evaluation(rec: Recorder, design: Any, fidelity: Fidelity, name: str,
                         on_step: StepFn | None = None, cache: EvaluationCache | None = None,
                         compute: Compute = DEFAULT) -> DesignEvaluation:
    """``evaluate_design(design, fidelity)``, replayed from the recorder when an earlier session has it,
    else served from the evaluation cache when it has it."""
    key = f"{name}|{fidelity}"
    found = _replayed(rec, key)
    if found is not None:
        return found
    ev = evaluate_design(design, fidelity, on_step, cache=cache, compute=compute)
    rec.record_stage(key, _baseline_payload(ev))
    return ev


#: what the baseline stage says of an evaluation computed in the side process meanwhile
BESIDE = "computed in worker processes beside the optimisation and the final evaluation"


def _provenance_note(*evaluations: DesignEvaluation) -> str:
    """Where each baseline evaluation came from: computed, replayed from the run record (``--resume``)
    or served from the evaluation cache (then the cache entry is named)."""
    unique = {id(ev): ev for ev in evaluations}.values()
    return "; ".join(f"{ev.fidelity} fidelity " + (ev.provenance or "computed") for ev in unique)


class ProblemRejected(InvalidInput):
    """The baseline evaluation shows the problem cannot run (a metric reference that picks no number):
    bad input found after the run directory was made (the CLI removes a fresh run's files)."""


def _run_locked(problem: Problem, out: Path, *, resume: bool, force: bool, scheduler: str, workers: int | None,
                progress: ProgressFn | None, export: bool, verify: bool, on_stage: Callable[[str], None] | None,
                verifier: Callable[[Any, str], Any] | None, on_step: StepFn | None = None,
                verify_worker: SupervisedWorker | None = None, cache: str | Path | None = None,
                side: Executor | None = None, compute: Compute = DEFAULT) -> PipelineResult:
    side = InlineExecutor() if side is None else side
    stages: list[StageOutcome] = []
    files: dict[str, str] = {}

    def stage(name: str) -> float:
        if on_stage is not None:
            on_stage(name)
        return time.perf_counter()

    def at(fidelity: Fidelity) -> StepFn | None:  # evaluator steps labelled with their fidelity
        if on_step is None:
            return None
        return lambda what, done, total: on_step(f"{fidelity}: {what}" if what else "", done, total)

    # the recorder exists before the baseline: a run killed during the baseline resumes too
    with make_executor(scheduler, workers=workers) as executor, \
            Recorder(out, fingerprint=problem.fingerprint(), resume=resume, force=force,
                     search_fingerprint=problem.search_fingerprint()) as rec, \
            (EvaluationCache(cache) if cache is not None else contextlib.nullcontext()) as ecache:
        # baseline at the optimisation fidelity: which metrics exist, from which evaluator
        t = stage("baseline")
        # the base design at the final fidelity: replayed or served from the cache at once, else computed
        # beside the run — its slow evaluators in the side process from the start, the others in the
        # optimisation's pool once the optimisation is done (not ahead of its points: each start waits for
        # its points in turn) — and collected at the final stage
        fid = problem.fidelity_final
        final_key = f"baseline|{fid}"
        baseline: DesignEvaluation | None = None
        pending_base: list[tuple[tuple[str, ...], Future]] = []
        slow = side_process.slow_evaluators(problem.device, fid)
        rest = tuple(e.name for e in EVALUATORS[problem.device] if e.name not in slow)
        beside = not side_process.in_process(side)

        def submit_base(names: tuple[str, ...], where: Executor) -> None:
            if names:
                pending_base.append((names, where.submit(side_process.evaluate, problem.base, fid, names,
                                                         compute=worker_compute(where, compute))))

        if fid != problem.fidelity_optimise:
            baseline = _replayed(rec, final_key)
            if baseline is None:
                hit = evaluation_cache.cached(problem.base, fid, ecache)
                if hit is not None:
                    baseline = _design_evaluation(hit)
                    rec.record_stage(final_key, _baseline_payload(baseline))
                elif beside:  # a head start: the side process imports and meshes during the draft baseline
                    submit_base(slow, side)
        base_opt = _recorded_evaluation(rec, problem.base, problem.fidelity_optimise, "baseline",
                                        at(problem.fidelity_optimise), ecache, compute)
        try:
            check_metrics(problem, base_opt.metrics)
        except (InvalidInput, UnknownName) as exc:
            raise ProblemRejected(str(exc)) from None
        only = evaluators_for(problem, base_opt)
        if fid == problem.fidelity_optimise:
            baseline = base_opt
        elif baseline is None and not beside:
            submit_base(slow, side)
            submit_base(rest, executor)
        note = _provenance_note(base_opt, *(() if baseline is None else (baseline,)))
        if baseline is None:
            note += f"; {fid} fidelity " + (BESIDE if beside else "computed")
        stages.append(StageOutcome(name="baseline", status="ok", wall_s=time.perf_counter() - t, message=note))

        rec.describe({**problem_info(problem), "status": "running"})
        rec.record_design("baseline", fidelity=str(problem.fidelity_optimise), x=problem.start,
                          design_toml=io.dumps(problem.base), metrics=base_opt.metrics, statuses=base_opt.statuses)
        t = stage("optimise")
        try:
            result = driver.run(problem, executor=executor, recorder=rec, metric_modules=base_opt.modules,
                                only=only, progress=progress, compute=compute)
        except BaseException:
            rec.set_status("interrupted")
            raise
        rec.end_session(status="optimised", n_evaluated=result.n_evaluated, n_replayed=result.n_replayed,
                        max_evals=problem.optimiser.max_evals)
        files["recorder"] = "evaluations.sqlite"
        stages.append(StageOutcome(name="optimise", status=result.status,
                                   message=f"{result.n_evaluated} evaluated, {result.n_replayed} replayed, "
                                           f"{result.n_cached} repeated points served from cache",
                                   wall_s=time.perf_counter() - t))

        if baseline is None and beside:
            submit_base(rest, executor)
        t = stage("final")
        best = result.best
        optimum_design = problem.design_at(best.x) if best is not None else problem.base
        optimum_design = dataclasses.replace(optimum_design, name=f"{problem.name}-optimum",
                                             description=f"optimum of problem {problem.name}")
        if baseline is None:  # computed beside the optimisation: collected (computed here if a process died)
            parts = [side_process.collect(f, lambda names=names: side_process.evaluate(problem.base, fid, names,
                                                                                         compute=compute))[0]
                     for names, f in pending_base]
            computed = evaluation_cache.merge(problem.base, parts)
            evaluation_cache.store(ecache, problem.base, computed, written_by="hapticopt optimise")
            baseline = _design_evaluation(computed)
            rec.record_stage(final_key, _baseline_payload(baseline))
        # computed (the plots need the evaluators' result objects), stored for compare and later runs: the
        # slow evaluators in the side process with their pictures, then the export there; the others here
        make_dirs(out / "plots", out)
        there = slow if beside else ()
        here = tuple(e.name for e in EVALUATORS[problem.device] if e.name not in there)
        pending_final = side.submit(side_process.evaluate, optimum_design, fid, there, out / "plots",
                                    compute=worker_compute(side, compute)) if there else None
        kept_export = _kept_export(out, optimum_design) if export and resume else None
        pending_export = side.submit(side_process.export, optimum_design, out) \
            if export and beside and kept_export is None else None
        parts = [evaluation_cache.evaluate(optimum_design, fid, cache=None, only=here, progress=at(fid),
                                           compute=compute)]
        side_drawn: dict[str, tuple[list[str], str]] = {}
        if there:
            side_ev, drawn = side_process.collect(pending_final, lambda: side_process.evaluate(
                optimum_design, fid, there, out / "plots", compute=compute))
            parts.append(side_ev)
            side_drawn = {name: (files, failure) for name, files, failure in drawn}
        merged = evaluation_cache.merge(optimum_design, parts)
        evaluation_cache.store(ecache, optimum_design, merged, written_by="hapticopt optimise")
        optimum = _design_evaluation(merged)
        cons = _constraints_at(problem, optimum.metrics)
        feasible_final = holds(cons, optimum.statuses)
        obj_base = problem.objective.metric.value(baseline.metrics)
        obj_opt = problem.objective.metric.value(optimum.metrics)
        sign = 1.0 if problem.objective.sense.value == "minimise" else -1.0
        improved = math.isfinite(obj_opt) and (not math.isfinite(obj_base) or sign * obj_opt < sign * obj_base)
        result_file = OPTIMUM_FILE if feasible_final else INFEASIBLE_FILE
        for stale in (OPTIMUM_FILE, INFEASIBLE_FILE):  # a resumed or forced run leaves one answer
            if stale != result_file:
                inside(out, stale).unlink(missing_ok=True)
        io.save_design(optimum_design, inside(out, result_file))
        rec.record_design("final", fidelity=str(problem.fidelity_final), x=best.x if best else problem.start,
                          design_toml=io.dumps(optimum_design), metrics=optimum.metrics, statuses=optimum.statuses)
        rec.set_status("finished")
    files["optimum" if feasible_final else "best_infeasible"] = result_file
    stages.append(StageOutcome(name="final", status="ok" if feasible_final else "infeasible",
                               message=f"re-evaluated at {problem.fidelity_final} fidelity"
                                       + (f" ({', '.join(there)} in a second process)" if there else ""),
                               wall_s=time.perf_counter() - t))

    t = stage("plots")
    plot_files: list[str] = []
    drawn = [e for e in EVALUATORS[problem.device] if e.plot is not None
             and (e.name in optimum.results or e.name in side_drawn)]
    for k, entry in enumerate(drawn):
        if on_step is not None:
            on_step(entry.name, k, len(drawn))
        try:
            if entry.name in side_drawn:  # drawn in the side process with its evaluation
                paths, failure = side_drawn[entry.name]
                if failure:
                    raise RuntimeError(failure)
            else:
                paths = run_plotter(entry, optimum_design, optimum.results[entry.name], out / "plots")
            for path in paths:
                plot_files.append(str(Path(path).resolve().relative_to(out.resolve())))
        except Exception as exc:  # noqa: BLE001 - a picture that fails is reported, the run goes on
            message = str(exc) if entry.name in side_drawn else describe_failure(exc)
            stages.append(StageOutcome(name=f"plot {entry.name}", status="failed", message=message))
    if on_step is not None:
        on_step("", len(drawn), len(drawn))
    stages.append(StageOutcome(name="plots", status="ok", wall_s=time.perf_counter() - t, files=tuple(plot_files)))

    if export and kept_export is not None:  # a resumed run whose optimum did not change: its export stands
        stages.append(StageOutcome(name="export", status="ok", wall_s=0.0, files=kept_export,
                                   message="the optimum is the one exported before: its files are kept, not "
                                           "recomputed"))
    elif export:
        t = stage("export")
        # beside: its own time there, and what this process waited for it; else (or its process died) here
        status, message, exported, wall_s = side_process.collect(
            pending_export, lambda: side_process.export(optimum_design, out, on_step))
        if beside:
            waited = time.perf_counter() - t
            where = f"in a second process beside the final evaluation and the plots ({waited:.3f} s waited here)"
            message = "; ".join(m for m in (message, where) if m)
        stages.append(StageOutcome(name="export", status=status, message=message, wall_s=wall_s, files=exported))
    verdicts: tuple[Verdict, ...] = ()
    if verify:
        t = stage("verify")
        vs, verdicts = _verify(optimum_design, problem.scenes, out, problem.fidelity_verify,
                               problem.verify_max_time_s, verifier, verify_worker, on_step,
                               worker_compute(verify_worker, compute))
        stages.append(dataclasses.replace(vs, wall_s=time.perf_counter() - t))

    t = stage("report")
    pres = PipelineResult(problem=problem, out_dir=out, run=result, baseline=baseline, optimum_design=optimum_design,
                          optimum=optimum, constraints_final=cons, feasible_final=feasible_final, improved=improved,
                          verdicts=verdicts, stages=tuple(stages), files=files)
    # the report set (convergence.svg, report.md, report.html, result.json) is written as one
    with file_set(out) as staged:
        files.update(report.write(pres, extra_stage=("report", t), dest=staged))
        _write_result_json(pres, staged)
    return pres


def _kept_export(out: Path, design: Any) -> tuple[str, ...] | None:
    """The files of the run's earlier export when it exported this very design (its optimum file holds
    the same TOML, result.json lists an ok export and every file is still there), else None."""
    try:
        previous = json.loads((out / "result.json").read_text(encoding="utf-8"))
        written = (out / OPTIMUM_FILE if (out / OPTIMUM_FILE).is_file() else out / INFEASIBLE_FILE).read_text(
            encoding="utf-8")
    except (OSError, ValueError):
        return None
    exported = previous.get("exported") if isinstance(previous, dict) else None
    ok = any(s.get("stage") == "export" and s.get("status") == "ok" for s in previous.get("stages", [])
             if isinstance(s, dict))
    if not ok or not isinstance(exported, list) or not exported or written != io.dumps(design):
        return None
    if not all(isinstance(f, str) and (out / f).is_file() for f in exported):
        return None
    return tuple(exported)


def _write_result_json(p: PipelineResult, dest: Path) -> None:
    best: EvalRecord | None = p.run.best
    payload = {
        "problem": p.problem.name,
        "status": p.run.status,
        "feasible_at_final_fidelity": p.feasible_final,
        "improved_on_baseline": p.improved,
        "objective": {"metric": p.problem.objective.metric.text, "sense": str(p.problem.objective.sense),
                      "baseline": p.problem.objective.metric.value(p.baseline.metrics),
                      "optimum": p.problem.objective.metric.value(p.optimum.metrics)},
        "best_x": dict(zip([v.key for v in p.problem.variables], best.x)) if best else None,
        "constraints_final": [{"constraint": t, "value": v, "satisfied": ok} for t, v, ok in p.constraints_final],
        "starts": [{"start": s.start, "status": str(s.status), "f": s.f, "message": s.message,
                    "rejected_draws": s.rejected_draws} for s in p.run.starts],
        "n_evaluated": p.run.n_evaluated, "n_replayed": p.run.n_replayed, "n_cached": p.run.n_cached,
        "notes": list(p.run.notes),
        "verdicts": [{"scene": v.scene, "passed": v.passed, "message": v.message} for v in p.verdicts],
        "stages": [{"stage": s.name, "status": s.status, "wall_s": s.wall_s, "message": s.message}
                   for s in p.stages],
        "files": p.files,
        "exported": [f for s in p.stages if s.name == "export" and s.status == "ok" for f in s.files],
    }
    write_text(inside(dest, "result.json"), strict_json.dumps(payload, indent=2) + "\n")


def run_front_pipeline(problem: Problem, *, out_dir: str | Path, resume: bool = False, force: bool = False,
                       scheduler: str = "local", workers: int | None = None,
                       progress: Callable[[str, int], None] | None = None,
                       cache: str | Path | None = None, compute: Compute = DEFAULT) -> dict[str, Any]:
    """A two-objective problem: trace the front (:func:`optim.pareto.run_front`), re-evaluate the
    chosen design at the final fidelity, write ``chosen.toml``, ``front.csv``, ``front.svg``,
    ``result.json`` and the report. Returns the ``result.json`` payload."""
    check_run_dir(out_dir, resume=resume, force=force)
    check_scheduler(scheduler)
    out = writable_dir(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with output_root(out), run_lock(out), children_die_with_this_process():
        remove_stale_temp_files(out)
        with (EvaluationCache(cache) if cache is not None else contextlib.nullcontext()) as ecache:
            return _run_front_locked(problem, out, resume=resume, force=force, scheduler=scheduler, workers=workers,
                                     progress=progress, cache=ecache, compute=compute)


def _run_front_locked(problem: Problem, out: Path, *, resume: bool, force: bool, scheduler: str,
                      workers: int | None, progress: Callable[[str, int], None] | None,
                      cache: EvaluationCache | None = None, compute: Compute = DEFAULT) -> dict[str, Any]:
    base_opt = evaluate_design(problem.base, problem.fidelity_optimise, cache=cache, compute=compute)
    check_metrics(problem, base_opt.metrics)
    single = dataclasses.replace(problem, objectives=(), pareto=None)
    needed = {base_opt.modules[r.name] for r in problem.all_metric_refs() if r.name in base_opt.modules}
    only = tuple(e.name for e in EVALUATORS[problem.device] if e.module in needed)
    rec = Recorder(out, fingerprint=problem.fingerprint(), resume=resume, force=force,
                   search_fingerprint=problem.search_fingerprint())
    try:
        info = problem_info(single, kind="pareto")
        info["objectives"] = [{"metric": o.metric.text, "sense": str(o.sense)} for o in problem.objectives]
        assert problem.pareto is not None
        info["pareto"] = {"method": "epsilon-constraint", "points": problem.pareto.points,
                          "choose": str(problem.pareto.choose), "weights": list(problem.pareto.weights)}
        rec.describe({**info, "status": "running"})
        rec.record_design("baseline", fidelity=str(problem.fidelity_optimise), x=problem.start,
                          design_toml=io.dumps(problem.base), metrics=base_opt.metrics, statuses=base_opt.statuses)
        with make_executor(scheduler, workers=workers) as executor:
            result = pareto.run_front(problem, executor=executor, recorder=rec, metric_modules=base_opt.modules,
                                      only=only, progress=progress, compute=compute)
        rec.end_session(status="front traced", n_evaluated=result.n_evaluated, n_replayed=result.n_replayed,
                        max_evals=problem.optimiser.max_evals)
        chosen = result.chosen
        chosen_design = problem.design_at(chosen.x) if chosen is not None else problem.base
        chosen_design = dataclasses.replace(chosen_design, name=f"{problem.name}-chosen",
                                            description=f"chosen design on the Pareto front of {problem.name}")
        final = evaluate_design(chosen_design, problem.fidelity_final, cache=cache, compute=compute)
        cons = _constraints_at(problem, final.metrics)
        feasible_final = holds(cons, final.statuses)
        rec.record_design("chosen", fidelity=str(problem.fidelity_final), x=chosen.x if chosen else problem.start,
                          design_toml=io.dumps(chosen_design), metrics=final.metrics, statuses=final.statuses)
        for p in result.front:
            rec.record_design("front", fidelity=str(problem.fidelity_optimise), x=p.x,
                              design_toml=io.dumps(problem.design_at(p.x)), metrics=p.metrics, statuses={})
        rec.set_status("finished")
    except BaseException:
        rec.set_status("interrupted")
        raise
    finally:
        rec.close()
    chosen_file = CHOSEN_FILE if feasible_final else CHOSEN_INFEASIBLE_FILE
    for stale in (CHOSEN_FILE, CHOSEN_INFEASIBLE_FILE):
        if stale != chosen_file:
            inside(out, stale).unlink(missing_ok=True)
    io.save_design(chosen_design, inside(out, chosen_file))
    files = pareto_report.write(result, problem, out, chosen_metrics=final.metrics, chosen_feasible=feasible_final,
                                fidelity_final=str(problem.fidelity_final))
    payload = {
        "problem": problem.name, "kind": "pareto", "method": "epsilon-constraint",
        "objectives": [{"metric": o.metric.text, "sense": str(o.sense)} for o in problem.objectives],
        "front": [{"run": p.run, "epsilon": None if math.isnan(p.epsilon) else p.epsilon,
                   "x": dict(zip([v.key for v in problem.variables], p.x)), "objectives": list(p.objectives)}
                  for p in result.front],
        "chosen": None if chosen is None else {"run": chosen.run,
                                               "x": dict(zip([v.key for v in problem.variables], chosen.x)),
                                               "objectives": list(chosen.objectives),
                                               "objectives_final": [o.metric.value(final.metrics)
                                                                    for o in problem.objectives],
                                               "feasible_at_final_fidelity": feasible_final},
        "runs": [{"run": label, "epsilon": None if math.isnan(eps) else eps, "status": res.status,
                  "n_evaluated": res.n_evaluated, "n_replayed": res.n_replayed} for label, eps, res in result.runs],
        "n_evaluated": result.n_evaluated, "n_replayed": result.n_replayed, "wall_s": result.wall_s,
        "files": {"chosen" if feasible_final else "chosen_infeasible": chosen_file, "recorder": "evaluations.sqlite",
                  **files},
    }
    write_text(inside(out, "result.json"), strict_json.dumps(payload, indent=2) + "\n")
    return payload
