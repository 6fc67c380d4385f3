"""One design's draft evaluation (``registry.evaluate_all``, the optimiser's path) in this tree against an
older revision's, side by side in one process: ``python benchmarks/ratio_single_draft.py REV [n [rounds]]``
(default the first n = 16 designs of ``bench_batched_draft.designs``, 7 rounds).

The older tree is loaded as in ``ratio_trees_draft`` (``git archive REV``, a second ``hapticopt`` package
taking turns in ``sys.modules``). Each tree first evaluates the designs one by one until its process-wide
count of checked poses passes ``interference_fast.KERNEL_AFTER_POSES`` (the optimiser's steady state: the
collision check's compiled kernel in use); then each round times, tree after tree (the first one alternating), the n
designs one by one. Prints ms per design (medians over the rounds), the ratio old / new, every design's results compared
(statuses equal, metrics equal bit for bit, NaN equal to NaN) and the load average before and after.
"""

from __future__ import annotations

import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_batched_draft import designs  # noqa: E402
from ratio_trees_draft import Tree, old_tree  # noqa: E402

from hapticopt.analysis.fidelity import Fidelity  # noqa: E402


def _same(a, b) -> bool:
    """Equal bit for bit (floats: the same value and sign, NaN equal to NaN), recursively."""
    if isinstance(a, float) and isinstance(b, float):
        return (math.isnan(a) and math.isnan(b)) or (a == b and math.copysign(1.0, a) == math.copysign(1.0, b))
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return type(a) is type(b) and a == b


def main(rev: str, n: int, rounds: int) -> None:
    print(f"load average before {' '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        trees = [old_tree(rev, Path(tmp)), Tree("new", {k: v for k, v in sys.modules.items()
                                                         if k == "hapticopt" or k.startswith("hapticopt.")})]
        Tree.active = trees[1]
        ds = designs(n)
        draft = Fidelity.DRAFT.value
        evals = {}
        for tree in trees:
            reg, fast = tree.mod("analysis.registry"), tree.mod("analysis.prrr.interference_fast")
            while True:
                evals[tree.label] = [reg.evaluate_all(d, fidelity=draft) for d in ds]
                if fast._POSES_CHECKED[0] >= fast.KERNEL_AFTER_POSES:
                    break
        t = {tree.label: [] for tree in trees}
        for k in range(rounds):
            for tree in (trees if k % 2 == 0 else trees[::-1]):  # each tree first in every other round
                reg = tree.mod("analysis.registry")
                t0 = time.perf_counter()
                for d in ds:
                    reg.evaluate_all(d, fidelity=draft)
                t[tree.label].append((time.perf_counter() - t0) / n)
        old, new = trees[0].label, trees[1].label
        same = sum(_same({k: str(v) for k, v in a.statuses.items()}, {k: str(v) for k, v in b.statuses.items()})
                   and _same(a.metrics(), b.metrics()) for a, b in zip(evals[old], evals[new]))
        mo, mn = statistics.median(t[old]), statistics.median(t[new])
        print(f"{n} designs one by one, {rounds} rounds, medians [ms/design]: {old}: {1e3 * mo:.3f}   "
              f"{new}: {1e3 * mn:.3f}   old/new {mo / mn:.3f}")
        print(f"results (statuses, metrics bit for bit) equal for {same} of {n} designs")
    print(f"load average after {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 16, int(sys.argv[3]) if len(sys.argv) > 3 else 7)
