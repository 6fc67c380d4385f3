"""First-call compile time and cached load time of the compiled MuJoCo loops (hapticopt.analysis.loop.mujoco_compiled).

Each measurement is a fresh process (numba compiles or loads once per process) running
``mujoco_compiled.warm_up()`` — import numba, load libmujoco, check the mjData layout, compile or load both
kernels — with ``NUMBA_CACHE_DIR`` set to a temporary folder: empty ("compile", the first run after an install
or a change of the kernels' source) or filled by the previous run ("load", every later run). Rounds interleaved,
medians; the same process also times ``import hapticopt.analysis.prrr.mujoco_plant`` (what a multibody run
imports anyway) as the yardstick the two are reported against.

    python benchmarks/mujoco_compile_time.py [rounds]
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile

CHILD = r"""
import json, time
t0 = time.perf_counter()
import hapticopt.analysis.prrr.mujoco_plant, hapticopt.analysis.master.mujoco_plant
t1 = time.perf_counter()
from hapticopt.analysis.loop import mujoco_compiled as mc
assert mc.warm_up() is None
t2 = time.perf_counter()
print(json.dumps({"imports": t1 - t0, "warm_up": t2 - t1}))
"""


def once(cache: str) -> dict[str, float]:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    out = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(rounds: int = 3) -> None:
    res: dict[str, list[dict[str, float]]] = {"compile": [], "load": []}
    for _ in range(rounds):
        with tempfile.TemporaryDirectory() as cache:
            res["compile"].append(once(cache))
            res["load"].append(once(cache))
    for kind, runs in res.items():
        w = statistics.median(r["warm_up"] for r in runs)
        imp = statistics.median(r["imports"] for r in runs)
        print(f"{kind:8s} warm_up median {w:.2f} s = {w / imp:.2f}x the plants' imports ({imp:.2f} s), {rounds} rounds")
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
