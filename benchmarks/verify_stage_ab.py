"""The verify stage (worker started and warmed before the stage, as the pipeline runs it) of two revisions side
by side: each round runs one fresh process per revision, interleaved; medians and the ratio new/old.

    python benchmarks/verify_stage_ab.py OLD_SHIM NEW_SHIM [problem] [rounds]

A shim is a folder with ``hapticopt/{design,analysis,optim}`` linking to a checkout (``PYTHONPATH`` for it).
Problems: ``prrr-workspace`` (the ``make run`` problem, on the recorded optimum) or ``master-transparency``
(on the master-paper preset).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys

CHILD = r"""
import sys, time
from pathlib import Path
from hapticopt.design import io
from hapticopt.optim import pipeline
from hapticopt.optim.problem import load_problem
name = sys.argv[1]
problem = load_problem(name)
design = (io.load_design(Path(sys.argv[2]) / "tests/optim/data/prrr-workspace-optimum.toml") if name == "prrr-workspace"
          else io.load_preset("master-paper"))
scenes, fid, limit = problem.scenes, problem.fidelity_verify, problem.verify_max_time_s
try:
    w = pipeline.verification_worker(scenes)
except TypeError:  # the revision before the warm-up hook
    w = pipeline.verification_worker()
with w:
    w.start()
    w.call(len, ((),), timeout_s=300)  # wait until started and warmed: the optimisation's time, not the stage's
    t = time.perf_counter()
    _, verdicts = pipeline._verify(design, scenes, Path("."), fid, limit, worker=w)
    print(time.perf_counter() - t, all(v.metrics for v in verdicts))
"""


def once(shim: str, problem: str) -> float:
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ, PYTHONPATH=shim)
    out = subprocess.run([sys.executable, "-c", CHILD, problem, root], env=env, capture_output=True, text=True,
                         check=True, cwd="/tmp")
    t, ok = out.stdout.split()[-2:]
    assert ok == "True", out.stdout
    return float(t)


if __name__ == "__main__":
    old, new = sys.argv[1], sys.argv[2]
    problem = sys.argv[3] if len(sys.argv) > 3 else "prrr-workspace"
    rounds = int(sys.argv[4]) if len(sys.argv) > 4 else 5
    times: dict[str, list[float]] = {"old": [], "new": []}
    for _ in range(rounds):
        times["old"].append(once(old, problem))
        times["new"].append(once(new, problem))
    mo, mn = statistics.median(times["old"]), statistics.median(times["new"])
    print(f"{problem}: verify stage old {mo:.2f} s, new {mn:.2f} s, new/old {mn / mo:.2f} "
          f"(median of {rounds}, interleaved; per-round ratios {[round(b / a, 2) for a, b in zip(times['old'], times['new'])]}); "
          f"load average {os.getloadavg()[0]:.2f}")
