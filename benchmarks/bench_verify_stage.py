"""The pipeline's verify stage (issue 22 target: ≤ 2 s for `hapticopt optimise prrr-workspace`, the
`make run` problem): its three scenes on the recorded optimum, side by side in one process —

* ``process_per_scene``: the previous implementation (a spawned process per scene), ≈ 2.5 s of
  start-up per scene;
* ``worker_cold``: :func:`hapticopt.optim.pipeline._verify` starting its one worker inside the stage;
* ``worker_warm``: the stage as the pipeline runs it, the worker started before the optimisation
  (its imports overlap with it), so the stage pays for the simulations only.

Run with ``make bench``, or ``python benchmarks/bench_verify_stage.py`` for the table in
docs/performance.md (medians of 5, interleaved).
"""

from __future__ import annotations

import os
import statistics
import time
from pathlib import Path


from hapticopt.design import io
from hapticopt.optim import pipeline
from hapticopt.optim.worker import SupervisedWorker
from hapticopt.optim.problem import load_problem

OPTIMUM = Path(__file__).resolve().parents[1] / "tests" / "optim" / "data" / "prrr-workspace-optimum.toml"
TARGET_S = 2.0


def process_per_scene(design, scenes, fidelity, max_time_s):
    """The verify stage before issue 22 (a spawned process per scene: start-up, imports, one scene), for
    comparison: a fresh worker per scene costs the same."""
    out = []
    for scene in scenes:
        with SupervisedWorker() as w:
            out.append(w.call(pipeline._scene_task, (design, scene, fidelity, None), timeout_s=max_time_s))
    return out


def measure(rounds: int = 5) -> dict[str, list[float]]:
    problem = load_problem("prrr-workspace")
    design = io.load_design(OPTIMUM)
    scenes, fid, limit = problem.scenes, problem.fidelity_verify, problem.verify_max_time_s
    times: dict[str, list[float]] = {"process_per_scene": [], "worker_cold": [], "worker_warm": []}
    for _ in range(rounds):
        t = time.perf_counter()
        old = process_per_scene(design, scenes, fid, limit)
        times["process_per_scene"].append(time.perf_counter() - t)
        assert all(o.kind == "ok" for o in old)
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


if __name__ == "__main__":
    t = measure()
    base = statistics.median(t["process_per_scene"])
    for k, v in t.items():
        m = statistics.median(v)
        print(f"{k:18s} median {m:6.2f} s  (min {min(v):.2f}, max {max(v):.2f})  {m / base:.2f}x of process_per_scene")
    print(f"load average {os.getloadavg()[0]:.1f}")
