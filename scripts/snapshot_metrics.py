"""Regenerate tests/snapshots/metrics.json: the metrics a refactoring must not change.

Runs ``hapticopt evaluate --json`` for the three presets at draft, standard and fine fidelity and
``hapticopt verify --json`` for the scenes ``stiffness-25``, ``free-space-x`` (on ``prrr-paper``),
``master-transparency`` (on ``master-paper``) and ``handle-ball`` (on ``handle-paper``), and stores
their JSON. Made on 1531152, before the one-path consolidation (issue 29);
``tests/test_metrics_snapshot.py`` compares the current code against it. A change that moves a
metric on purpose regenerates the snapshot with this script and says why in its commit.

    .venv/bin/python scripts/snapshot_metrics.py [OUT.json] [CASE ...]
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXE = str(Path(sys.executable).with_name("hapticopt"))

PRESETS = ("prrr-paper", "master-paper", "handle-paper")
FIDELITIES = ("draft", "standard", "fine")
SCENES = (("prrr-paper", "stiffness-25"), ("prrr-paper", "free-space-x"),
          ("master-paper", "master-transparency"), ("handle-paper", "handle-ball"))

CASES = {f"evaluate {p} {f}": ["evaluate", "--preset", p, "--fidelity", f, "--json"]
         for p in PRESETS for f in FIDELITIES}
CASES |= {f"verify {p} {s}": ["verify", "--preset", p, "--scene", s, "--json"] for p, s in SCENES}


def run_case(args: list[str]) -> object:
    out = subprocess.run([EXE, *args], capture_output=True, text=True, check=False)
    if out.returncode not in (0, 3):
        raise RuntimeError(f"{' '.join(args)}: exit {out.returncode}: {out.stderr.strip()}")
    return json.loads(out.stdout)


def main() -> None:
    dest = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "tests" / "snapshots" / "metrics.json"
    names = sys.argv[2:] or list(CASES)
    snap = json.loads(dest.read_text()) if sys.argv[2:] and dest.exists() else {}
    for name in names:
        snap[name] = run_case(CASES[name])
        print(f"{name}: done", flush=True)
    dest.write_text(json.dumps(snap, indent=1, sort_keys=True) + "\n")
    print(f"wrote {dest}")


if __name__ == "__main__":
    main()
