"""The pipeline's side process: the slow evaluators and the export, beside the main process's work.

A run's slowest work at the final fidelity does not depend on the optimisation: the evaluators marked
slow at a fidelity (:attr:`hapticopt.analysis.registry.EvaluatorEntry.slow_at`, the CAD solid FEA of
the 3-PRRR at fine fidelity) of the base design run here while the draft baseline and the
optimisation run in the main process and its pool; then those of the optimum, with their pictures,
and the optimum's export (the three need the CAD kernel, imported once, here). The main process
computes the other evaluators meanwhile. Where a value is computed does not change it: each
evaluation is a pure function of its design and fidelity, and the parts are merged in the registry's
order (:func:`hapticopt.optim.cache.merge`).

One spawned process (a forked jax runtime is not safe) behind an :class:`~concurrent.futures.Executor`,
or the calling thread for the ``inline`` scheduler (the same code path, run in turn). This module's
imports are kept small: the process imports it before its first task, while the optimisation runs.
"""

from __future__ import annotations

import contextlib
import dataclasses
import multiprocessing
import os
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from pathlib import Path
from typing import Any

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.registry import EVALUATORS, describe_failure, run_plotter
from hapticopt.optim import cache as evaluation_cache
from hapticopt.optim.cache import CachedEvaluation
from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.optim.executor import InlineExecutor, start_child


@contextlib.contextmanager
def side_executor(scheduler: str) -> Iterator[Executor]:
    """The side process for a run on ``scheduler`` (inline: this thread). A run that stops early (an
    exception, Ctrl-C) kills the process instead of waiting for its evaluation."""
    if scheduler == "inline":
        yield InlineExecutor()
        return
    pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                               initializer=start_child, initargs=(os.getpid(),))
    try:
        yield pool
    except BaseException:
        for proc in list((getattr(pool, "_processes", None) or {}).values()):  # running work is not waited for
            proc.kill()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


def in_process(executor: Executor) -> bool:
    """Whether ``executor`` runs its tasks in the calling thread (no overlap)."""
    return isinstance(executor, InlineExecutor)


def slow_evaluators(device: str, fidelity: Fidelity) -> tuple[str, ...]:
    """The evaluators of ``device`` marked slow at ``fidelity``, in the registry's order."""
    return tuple(e.name for e in EVALUATORS[device] if str(Fidelity(fidelity)) in e.slow_at)


def evaluate(design: Any, fidelity: Fidelity, only: tuple[str, ...],
             plots_dir: Path | None = None, compute: Compute = DEFAULT
             ) -> tuple[CachedEvaluation, list[tuple[str, list[str], str]]]:
    """The evaluators ``only`` of ``design`` at ``fidelity`` (no cache: the caller stores the merged
    evaluation) and, with ``plots_dir``, their pictures there. Returns (the evaluation without its
    result objects, [(evaluator, picture files, failure message or '')])."""
    ev = evaluation_cache.evaluate(design, fidelity, cache=None, only=only, compute=compute)
    drawn = []
    if plots_dir is not None:
        for entry in EVALUATORS[design.device]:
            if entry.plot is None or entry.name not in ev.results:
                continue
            try:
                files = [str(p) for p in run_plotter(entry, design, ev.results[entry.name], plots_dir)]
                drawn.append((entry.name, files, ""))
            except Exception as exc:  # noqa: BLE001 - a picture that fails is reported, the run goes on
                drawn.append((entry.name, [], describe_failure(exc)))
    return dataclasses.replace(ev, results={}), drawn


def export(design: Any, out_dir: Path, on_step: Callable[[str, int, int], None] | None = None
           ) -> tuple[str, str, tuple[str, ...], float]:
    """STEP, STLs, MJCF, mass properties and the render of ``design`` into ``out_dir``
    (:func:`hapticopt.design.export.export`, ``on_step`` its progress hook): (status, message, files
    relative to ``out_dir``, wall time [s]); a failure is the status ``failed`` with its message."""
    from hapticopt.design import export as design_export

    t0 = time.perf_counter()
    try:
        limits = None
        if design.device == "prrr":  # the MJCF's R-joint ranges from the joint-limits evaluator
            from hapticopt.analysis.prrr.loop.mujoco_model import export_joint_limits
            limits = export_joint_limits(design)
        result = design_export.export(design, out_dir, render=True, joint_limits=limits,
                                      **({} if on_step is None else {"on_step": on_step}))
    except Exception as exc:  # noqa: BLE001 - a failed export is reported in the report
        return "failed", describe_failure(exc), (), time.perf_counter() - t0
    files = tuple(sorted(str(Path(p).resolve().relative_to(Path(out_dir).resolve())) for p in result.files))
    return "ok", "", files, time.perf_counter() - t0


def collect(future: Future | None, fallback: Callable[[], Any]) -> Any:
    """The task's value; computed here by ``fallback`` when the side process could not deliver it (it
    died, a value did not pickle): the tasks report their own failures as values, so an exception
    here is the process's, and the run's results never depend on where they were computed."""
    if future is None:
        return fallback()
    try:
        return future.result()
    except Exception:  # noqa: BLE001 - see above
        return fallback()
