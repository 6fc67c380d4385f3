"""Kill the pipeline with SIGKILL at random moments, resume it, and check the issue-14 promises.

    PYTHONPATH=... python scripts/kill_resume.py [N_KILLS] [SEED] [STAGE,STAGE,...] [MAX_DELAY_S]

For each kill: a fresh run directory; the pipeline (tests/optim/data/pipeline_run.py --export:
baseline, optimise on a 2-worker pool, final, plots, export, verification in its worker process,
report) is killed with SIGKILL a random 0–1.5 s after a stage begins (the stages in turn, so
every stage is hit; "start" is the process start, before the run directory exists); then resumed
to the end. Checked: children gone within 5 s, the resumed result equal to the uninterrupted one,
no evaluation repeated, no temp file left. Prints a markdown table.
"""

from __future__ import annotations

import json
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STAGES = ("start", "baseline", "optimise", "final", "plots", "export", "verify", "report")
sys.path.insert(0, str(ROOT / "tests" / "optim"))
import killing  # noqa: E402


def run_to_end(run: Path, *args: str) -> tuple[dict, float]:
    t0 = time.monotonic()
    out = subprocess.run([sys.executable, str(killing.SCRIPT), str(run), *args], env=killing.env(),
                         capture_output=True, text=True, timeout=600)
    if out.returncode != 0:
        raise SystemExit(f"run failed: {out.stderr[-1500:]}")
    return json.loads(out.stdout.strip().splitlines()[-1]), time.monotonic() - t0


def main(n_kills: int = 10, seed: int = 14, stages: tuple[str, ...] = STAGES, max_delay_s: float = 1.5) -> None:
    rng = random.Random(seed)
    with tempfile.TemporaryDirectory() as d:
        base = Path(d)
        reference, t_ref = run_to_end(base / "reference", "--export")
        n_ref = killing.recorded(base / "reference")[0]
        print(f"uninterrupted: {t_ref:.1f} s, {n_ref} evaluations, best_x {reference['best_x']}\n")
        print("| kill | aimed at | at [s] | stage killed in | evaluations recorded | children | gone after [s] | resumed: "
              "replayed / evaluated | same result | repeated | leftovers |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        ok = True
        for k in range(n_kills):
            run, log = base / f"run{k}", base / f"stages{k}.log"
            target = stages[k % len(stages)]
            delay = rng.uniform(0.0, max_delay_s)
            p = subprocess.Popen([sys.executable, str(killing.SCRIPT), str(run), "--export", "--stage-log", str(log)],
                                 env=killing.env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            while p.poll() is None and not (log.exists() and target in log.read_text().split()):
                time.sleep(0.01)
            t_kill = time.time() + delay
            killed, kids, gone = killing.kill_after(p, delay)
            logged = [ln.split() for ln in log.read_text().splitlines()] if log.exists() else []
            stage = ([s for t, s in logged if float(t) <= t_kill] or ["start"])[-1]
            at = t_kill - float(logged[0][0]) if logged else delay
            n_before = killing.recorded(run)[0]
            res, _ = run_to_end(run, "--resume" if (run / "evaluations.sqlite").exists() else "", "--export")
            same = res["best_x"] == reference["best_x"] and res["best_f"] == reference["best_f"]
            repeated = (res["n_evaluated"] + res["n_replayed"]) - n_ref if killed else 0
            rows_ok = killing.recorded(run)[0] == n_ref
            left = killing.leftovers(run)
            good = same and repeated == 0 and rows_ok and not left and gone <= 5.0
            ok &= good
            print(f"| {k} | {target} + {delay:.2f} | {at:.1f} | {stage if killed else '(finished first)'} | {n_before} | {len(kids)} | "
                  f"{gone:.2f} | {res['n_replayed']} / {res['n_evaluated']} | {'yes' if same else 'NO'} | "
                  f"{repeated} | {len(left)} |")
        print("\nall promises held" if ok else "\nSOME PROMISE BROKEN")


if __name__ == "__main__":
    # kill_resume.py [N_KILLS] [SEED] [STAGE,STAGE,...] [MAX_DELAY_S]
    a = sys.argv[1:]
    main(int(a[0]) if a else 10, int(a[1]) if len(a) > 1 else 14,
         tuple(a[2].split(",")) if len(a) > 2 else STAGES, float(a[3]) if len(a) > 3 else 1.5)
