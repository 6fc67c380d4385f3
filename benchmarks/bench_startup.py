"""Cold start of the command line: a fresh interpreter each round.

Run: ``pytest benchmarks/bench_startup.py -o python_files='bench_*.py' --benchmark-enable``
(wall time of ``import hapticopt.optim.cli``, ``hapticopt --help``, and ``hapticopt evaluate --preset
prrr-paper`` to its first byte of output). Against another revision: ``benchmarks/ab.py REV startup``.
"""

from __future__ import annotations

import os
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

