"""Helper for the kill-and-resume test (tests/optim/test_pipeline.py): the whole pipeline on a small
problem with a process pool (children to kill), the plots, a stand-in verifier in its child
process and the report. Usage: pipeline_run.py RUN_DIR [--resume] [--export] [--stage-log FILE] (appends "time stage" lines)."""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

import fake_verifier

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.optim.pipeline import run_pipeline
from hapticopt.optim.problem import load_problem

PROBLEM = Path(__file__).with_name("beta-isotropic.toml")


def main(argv: list[str]) -> None:
    problem = dataclasses.replace(load_problem(PROBLEM), scenes=("free-space", "slow-scene"), verify_max_time_s=20.0)
    problem = problem.with_optimiser(max_evals=30, starts=2)
    log = Path(argv[argv.index("--stage-log") + 1]) if "--stage-log" in argv else None

    def on_stage(name: str) -> None:
        if log is not None:
            with open(log, "a") as fh:
                fh.write(f"{time.time():.3f} {name}\n")

    on_stage("start")
    res = run_pipeline(problem, out_dir=argv[0], resume="--resume" in argv, scheduler="local", workers=2,
                       export="--export" in argv, verify=True, verifier=fake_verifier.run_scene, on_stage=on_stage)
    on_stage("done")
    print(json.dumps({"best_x": list(res.run.best.x), "best_f": res.run.best.f, "n_evaluated": res.run.n_evaluated,
                      "n_replayed": res.run.n_replayed, "verdicts": [[v.scene, v.passed] for v in res.verdicts],
                      "baseline": res.problem.objective.metric.value(res.baseline.metrics)}))


if __name__ == "__main__":
    main(sys.argv[1:])
