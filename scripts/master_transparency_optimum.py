"""Regenerate the recorded optimum of the bundled problem master-transparency.

Run: .venv/bin/python scripts/master_transparency_optimum.py [--from DIR]

Without ``--from`` it runs the bundled command into a temporary directory,

    hapticopt optimise master-transparency --out DIR --workers 1 --no-export --no-verify

(GN_ISRES seed 1, then the COBYLA polish; 15-20 min on the shared 2-core machine); with ``--from DIR``
it reads a finished run of that command. It writes ``tests/snapshots/master_transparency_optimum.json``
(the optimum's counterweights, objective and constraint values at the final fidelity, the number of
evaluations, and the run's first ``PREFIX`` search points with their values, which
``tests/analysis/master/test_seed003_protocol.py`` reproduces at a reduced budget) and prints the
optimum's row of the table in docs/master.md.
"""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SNAPSHOT = ROOT / "tests" / "snapshots" / "master_transparency_optimum.json"
#: search points of the full run a reduced-budget run must reproduce: its budget × GLOBAL_SHARE (20 × 0.7)
PREFIX = 14
KEYS = ("upper_mass_kg", "upper_distance_mm", "forearm_mass_kg", "forearm_distance_mm")


def run_command(out: Path) -> None:
    cmd = [sys.executable, "-m", "hapticopt.optim.cli", "optimise", "master-transparency", "--out", str(out),
           "--workers", "1", "--no-export", "--no-verify", "--quiet"]
    subprocess.run(cmd, check=False, cwd=ROOT)


def read_run(out: Path) -> dict:
    res = json.loads((out / "result.json").read_text())
    x = {k.split(".", 1)[1]: v for k, v in res["best_x"].items()}
    cons = {c["constraint"]: c["value"] for c in res["constraints_final"]}
    con = sqlite3.connect(f"file:{out / 'evaluations.sqlite'}?mode=ro", uri=True)
    rows = con.execute("select x, vals from evaluations where stage = 'search' order by id limit ?", (PREFIX,)).fetchall()
    con.close()
    return {
        "_comment": ("Regression snapshot (issue 31): the optimum of the bundled problem master-transparency as "
                     "`hapticopt optimise master-transparency --out DIR --workers 1 --no-export --no-verify` yields "
                     "it, written by scripts/master_transparency_optimum.py (do not edit by hand). search_prefix: "
                     f"the run's first {PREFIX} GN_ISRES points [x, values], which a 20-evaluation run reproduces."),
        "counterweights": {k: x[k] for k in KEYS},
        "objective_Hz": res["objective"]["optimum"],
        "baseline_Hz": res["objective"]["baseline"],
        "max_unbalance_force_N": cons["max_unbalance_force_N <= 0.1"],
        "workspace_coverage": cons["workspace_coverage >= 0.99"],
        "n_evaluated": res["n_evaluated"],
        "search_prefix": [[json.loads(a), json.loads(b)] for a, b in rows],
    }


def main() -> None:
    if "--from" in sys.argv:
        snap = read_run(Path(sys.argv[sys.argv.index("--from") + 1]))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            run_command(Path(tmp) / "run")
            snap = read_run(Path(tmp) / "run")
    SNAPSHOT.write_text(json.dumps(snap, indent=2) + "\n")
    c = snap["counterweights"]
    print(f"| optimum | {c['upper_mass_kg'] * 1e3:.1f} g at {c['upper_distance_mm']:.1f} mm "
          f"| {c['forearm_mass_kg'] * 1e3:.1f} g at {c['forearm_distance_mm']:.1f} mm "
          f"| min(x, z) {snap['objective_Hz']:.2f} Hz (baseline {snap['baseline_Hz']:.2f}) "
          f"| {snap['max_unbalance_force_N']:.4f} | {snap['n_evaluated']} evaluations |")


if __name__ == "__main__":
    main()
