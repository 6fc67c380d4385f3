"""Cold start of the command line (issue 22 item 5): a fresh interpreter each round.

Run: ``pytest benchmarks/bench_startup.py -o python_files='bench_*.py' --benchmark-enable``
(wall time of ``import hapticopt.optim.cli``, ``hapticopt --help``, and ``hapticopt evaluate --preset
prrr-paper`` to its first byte of output).

Side by side against another checkout (medians of N interleaved cold starts, and the ratio)::

    python benchmarks/bench_startup.py --before /path/to/shim-of-old-tree [--rounds 7]

where each argument is a ``PYTHONPATH`` under which ``import hapticopt`` finds that tree.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

import pytest

IMPORT = ["-c", "import hapticopt.optim.cli"]
HELP = ["-c", "import sys; sys.argv = ['hapticopt', '--help']; from hapticopt.optim.cli import main; main()"]
EVALUATE = ["-c", "import sys; sys.argv = ['hapticopt', 'evaluate', '--preset', 'prrr-paper']; "
                  "from hapticopt.optim.cli import main; main()"]
CASES = {"import hapticopt.optim.cli": IMPORT, "hapticopt --help": HELP,
         "hapticopt evaluate --preset prrr-paper (first output)": EVALUATE}


def first_output_s(args: list[str], pythonpath: str | None = None) -> float:
    """Wall time [s] from starting ``python ARGS`` to its first byte on stdout (or its exit)."""
    env = dict(os.environ)
    if pythonpath is not None:
        env["PYTHONPATH"] = pythonpath
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, *args], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env)
    assert proc.stdout is not None
    proc.stdout.read(1)
    t = time.perf_counter() - t0
    proc.stdout.read()
    proc.stdout.close()
    if proc.wait() != 0:
        raise RuntimeError(f"{args} exited {proc.returncode}")
    return t


@pytest.mark.parametrize("case", list(CASES))
def test_cold_start(benchmark, case):
    benchmark.pedantic(first_output_s, args=(CASES[case],), rounds=5, iterations=1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", required=True, help="PYTHONPATH of the tree to compare against")
    ap.add_argument("--after", default=os.environ.get("PYTHONPATH"), help="PYTHONPATH of this tree (default: $PYTHONPATH)")
    ap.add_argument("--rounds", type=int, default=7)
    ns = ap.parse_args()
    for name, args in CASES.items():
        before, after = [], []
        for _ in range(ns.rounds):  # interleaved: load changes hit both alike
            before.append(first_output_s(args, ns.before))
            after.append(first_output_s(args, ns.after))
        b, a = statistics.median(before), statistics.median(after)
        print(f"{name}: before median {b:.3f} s, after median {a:.3f} s, ratio before/after {b / a:.2f} "
              f"({ns.rounds} interleaved cold starts each)")


if __name__ == "__main__":
    main()
