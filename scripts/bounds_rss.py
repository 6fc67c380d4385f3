"""Peak memory (max RSS, every process of the command) and wall time of hapticopt at the edges of what
it accepts (issue 37: "no accepted input makes a process exceed 2 GB RSS or run past its documented
time bound"). Each case runs the CLI in a fresh process at the largest value its bound allows.

    python scripts/bounds_rss.py [--out DIR] [CASE ...]

Prints one line per case: the case, exit code, wall seconds, peak RSS of the largest process in MB
(``ru_maxrss`` of the waited children: the CLI and, after they end, its pool workers)."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HAPTICOPT = str(Path(sys.executable).with_name("hapticopt"))


_WRAP = ("import resource, subprocess, sys\n"
         "p = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL)\n"
         "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr)\n"
         "sys.exit(p.returncode)")


def cases(tmp: Path) -> dict[str, list[str]]:
    big = tmp / "big.toml"  # a design file at the 1 MB input limit (a long description is cut by the reader)
    big.write_text('name = "big"\ndevice = "prrr"\n' + "# " + "x" * 998_000 + "\n")
    return {
        # MAX_TICKS = 1e6 controller ticks (optim/cli/verify.py): the scene's duration / 1e6
        "verify-prrr-1e6-ticks": ["verify", "--preset", "prrr-paper", "--scene", "stiffness-25", "--period-ms", "AUTO",
                                  "--json"],
        "verify-master-1e6-ticks": ["verify", "--preset", "master-paper", "--scene", "master-wall", "--period-ms", "AUTO",
                                    "--json"],
        "export-1000-poses": ["export", "--preset", "prrr-paper", "--poses", "1000", "--out", str(tmp / "export")],
        "sweep-100000-points": ["sweep", "--preset", "prrr-paper", "geometry.beta_deg=40:60:100000", "--batch",
                                "--no-plots", "--quiet", "--out", str(tmp / "sweep")],
        "evaluate-1MB-file": ["evaluate", str(big), "--fidelity", "draft", "--json"],
    }


def scene_duration_s(preset: str, scene: str) -> float:
    code = ("from hapticopt.analysis.loop.scene import load_scene\n"
            f"print(load_scene({scene!r}).duration)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(out.stdout.strip())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("cases", nargs="*")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        table = cases(Path(tmp))
        for name in args.cases or table:
            argv = table[name]
            if "AUTO" in argv:
                dur = scene_duration_s(argv[argv.index("--preset") + 1], argv[argv.index("--scene") + 1])
                argv = [f"{dur / 1e6 * 1e3 * 1.0000001:.9g}" if a == "AUTO" else a for a in argv]
            t0 = time.monotonic()
            # a fresh wrapper per case: its RUSAGE_CHILDREN peak is the largest process of this case alone
            # (the CLI, and its pool workers, which the CLI waits for)
            p = subprocess.run([sys.executable, "-c", _WRAP, HAPTICOPT, *argv], capture_output=True, text=True, cwd=tmp)
            wall = time.monotonic() - t0
            *err, peak = p.stderr.strip().splitlines()
            code = p.returncode
            note = err[-1][:100] if code and err else ""
            print(f"{name:28s} exit {code}  wall {wall:7.1f} s  peak RSS {int(peak) / 1024:7.0f} MB  {note}", flush=True)


if __name__ == "__main__":
    os.environ.setdefault("PYTHONWARNINGS", "ignore")
    main()
