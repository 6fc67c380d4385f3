"""The pipeline's verify stage (target: ≤ 2 s for `hapticopt optimise prrr-workspace`, the
`make run` problem): its three scenes on the recorded optimum, side by side in one process —

* ``worker_cold``: :func:`hapticopt.optim.pipeline._verify` starting its one worker inside the stage;
* ``worker_warm``: the stage as the pipeline runs it, the worker started before the optimisation
  (its imports overlap with it), so the stage pays for the simulations only.

Run with ``make bench``; against another revision: ``benchmarks/ab.py REV verify --scene S``.
"""

from __future__ import annotations

import os
import statistics
import time
from pathlib import Path

from hapticopt.design import io
from hapticopt.optim import pipeline
from hapticopt.optim.problem import load_problem

OPTIMUM = Path(__file__).resolve().parents[1] / "tests" / "optim" / "data" / "prrr-workspace-optimum.toml"
TARGET_S = 2.0


def measure(rounds: int = 5) -> dict[str, list[float]]:
    problem = load_problem("prrr-workspace")
    design = io.load_design(OPTIMUM)
    scenes, fid, limit = problem.scenes, problem.fidelity_verify, problem.verify_max_time_s
    times: dict[str, list[float]] = {"worker_cold": [], "worker_warm": []}
    for _ in range(rounds):
        t = time.perf_counter()
        _, verdicts = pipeline._verify(design, scenes, Path("."), fid, limit)
        times["worker_cold"].append(time.perf_counter() - t)
        assert all(v.metrics for v in verdicts)
        with pipeline.verification_worker() as w:
            w.start()
            w.call(pipeline.warm_verification, (), timeout_s=120)  # the optimisation's time, not the stage's
            t = time.perf_counter()
            _, verdicts = pipeline._verify(design, scenes, Path("."), fid, limit, worker=w)
            times["worker_warm"].append(time.perf_counter() - t)
        assert all(v.metrics for v in verdicts)
    return times


def test_verify_stage(benchmark):
    times = benchmark.pedantic(measure, rounds=1, iterations=1)
    med = {k: statistics.median(v) for k, v in times.items()}
    benchmark.extra_info.update({f"{k}_s": v for k, v in med.items()} | {"load_average": os.getloadavg()[0]})
    assert med["worker_warm"] <= TARGET_S

