"""Helper for tests/optim/test_recorder.py: a recorded optimisation whose evaluations are slowed
down (sleep) so that the test can SIGKILL it mid-run. Usage: slow_run.py RUN_DIR [--resume] [--delay S]."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.optim import driver
from hapticopt.optim.evaluation import evaluate_point
from hapticopt.optim.problem import load_problem
from hapticopt.optim.recorder import Recorder

ONLY = ("statics",)  # the problem's metrics all come from hapticopt.analysis.prrr.structure.statics
PROBLEM = Path(__file__).with_name("resume-problem.toml")
DELAY = 0.0


def slow_evaluate(task):
    time.sleep(DELAY)
    return evaluate_point(task)


def main(argv: list[str]) -> None:
    global DELAY
    run_dir = Path(argv[0])
    resume = "--resume" in argv
    if "--delay" in argv:
        DELAY = float(argv[argv.index("--delay") + 1])
    problem = load_problem(PROBLEM)
    with Recorder(run_dir, fingerprint=problem.fingerprint(), resume=resume) as rec:
        res = driver.run(problem, only=ONLY, recorder=rec, evaluate_fn=slow_evaluate)
    print(json.dumps({"best_x": res.best.x, "best_f": res.best.f, "n_evaluated": res.n_evaluated,
                      "n_replayed": res.n_replayed, "history": [[list(r.x), r.f] for r in res.history]}))


if __name__ == "__main__":
    main(sys.argv[1:])
