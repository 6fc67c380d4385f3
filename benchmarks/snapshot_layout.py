"""Regenerate tests/snapshots/layout_metrics.json: the metrics the layout move must not change.

Runs ``hapticopt evaluate --json`` for both presets at draft and standard fidelity and
``hapticopt verify --json`` for the scenes ``stiffness-25`` and ``master-transparency`` (the
latter on ``master-paper``), and stores their JSON. Made before the modules moved (issue: one
house for two devices); ``tests/test_layout_snapshot.py`` compares the current code against it.

    .venv/bin/python benchmarks/snapshot_layout.py [OUT.json]
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXE = str(Path(sys.executable).with_name("hapticopt"))

CASES = {
    "evaluate prrr-paper draft": ["evaluate", "--preset", "prrr-paper", "--fidelity", "draft", "--json"],
    "evaluate prrr-paper standard": ["evaluate", "--preset", "prrr-paper", "--fidelity", "standard", "--json"],
    "evaluate master-paper draft": ["evaluate", "--preset", "master-paper", "--fidelity", "draft", "--json"],
    "evaluate master-paper standard": ["evaluate", "--preset", "master-paper", "--fidelity", "standard", "--json"],
    "verify prrr-paper stiffness-25": ["verify", "--preset", "prrr-paper", "--scene", "stiffness-25", "--json"],
    "verify master-paper master-transparency": ["verify", "--preset", "master-paper", "--scene", "master-transparency", "--json"],
}


def run_case(args: list[str]) -> object:
    out = subprocess.run([EXE, *args], capture_output=True, text=True, check=False)
    if out.returncode not in (0, 3):
        raise RuntimeError(f"{' '.join(args)}: exit {out.returncode}: {out.stderr.strip()}")
    return json.loads(out.stdout)


def main() -> None:
    dest = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "tests" / "snapshots" / "layout_metrics.json"
    snap = {name: run_case(args) for name, args in CASES.items()}
    dest.write_text(json.dumps(snap, indent=1, sort_keys=True) + "\n")
    print(f"wrote {dest}")


if __name__ == "__main__":
    main()
