"""The pipeline's baseline stage of a second ``make run``-like invocation, cold vs warm evaluation cache


The stage is what :func:`hapticopt.optim.pipeline.run_pipeline` does before optimising
``prrr-workspace``: the base design (``prrr-paper``) at the optimisation fidelity (draft) and at the
final fidelity (fine), each through :func:`hapticopt.optim.pipeline._recorded_evaluation` with a
new run record (a fresh ``--out``, or ``--force``: nothing to replay). Cold: no cache (every run
before this branch; ``--no-cache``). Warm: the cache file already holds both evaluations (written by
an earlier run).

Run: ``pytest benchmarks/bench_cache.py -o python_files='bench_*.py' --benchmark-enable`` (in one
process: jit and imports warm after the first round).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from hapticopt.optim.cache import EvaluationCache
from hapticopt.optim.pipeline import _provenance_note, _recorded_evaluation
from hapticopt.optim.problem import load_problem
from hapticopt.optim.recorder import Recorder

PROBLEM = "prrr-workspace"


def baseline_stage(out: Path, cache: Path | None) -> dict:
    """Run the baseline stage of PROBLEM into a new run directory ``out``; stage wall time and provenance."""
    problem = load_problem(PROBLEM)
    t0 = time.perf_counter()
    with Recorder(out, fingerprint="bench", resume=False, force=True) as rec, \
            EvaluationCache(cache) if cache is not None else _Null() as ecache:
        draft = _recorded_evaluation(rec, problem.base, problem.fidelity_optimise, "baseline", cache=ecache)
        fine = _recorded_evaluation(rec, problem.base, problem.fidelity_final, "baseline", cache=ecache)
    return {"stage_s": time.perf_counter() - t0, "provenance": _provenance_note(draft, fine),
            "metrics": json.dumps(fine.metrics)}


class _Null:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return None


@pytest.mark.parametrize("warm", [False, True], ids=["cold", "warm"])
def test_baseline_stage(benchmark, tmp_path, warm):
    cache = tmp_path / "evaluation-cache.sqlite"
    if warm:
        baseline_stage(tmp_path / "fill", cache)
    counter = iter(range(1000))
    result = benchmark.pedantic(lambda: baseline_stage(tmp_path / f"run{next(counter)}", cache if warm else None),
                                rounds=3 if not warm else 5, iterations=1)
    assert ("from the evaluation cache" in result["provenance"]) == warm

