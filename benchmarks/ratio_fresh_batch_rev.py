"""The batched draft evaluation of designs never evaluated before in the process (as an optimiser's or a
sweep's batches are), this tree against an older revision, both trees whole, side by side in one
process (interleaved rounds, medians): ``python benchmarks/ratio_fresh_batch_rev.py REV [n [rounds]]``
(default n = 1024, 5 rounds).

``ratio_trees_draft.py`` times the same designs round after round, so every per-design cache (the
chain-closure verdict, the CAD layout check) is warm there; here each round draws new designs
(``bench_batched_draft.designs`` with seed 1000 + round, the same for both trees; each tree has its own
caches), and the warm batch of the first designs is timed beside them; the trees take turns first
(old first in even rounds). Prints wall and process CPU ms per design (CPU: every thread of the
process, less sensitive to other jobs on a shared machine), the ratios old / new, and the load average
before and after.
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
from pathlib import Path
import time

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_batched_draft import designs  # noqa: E402
from ratio_trees_draft import Tree, _ours, old_tree  # noqa: E402

from hapticopt.analysis.fidelity import Fidelity  # noqa: E402


def main(rev: str, n: int, rounds: int) -> None:
    print(f"load average before {' '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)
    draft = Fidelity.DRAFT.value
    with tempfile.TemporaryDirectory() as tmp:
        trees = [old_tree(rev, Path(tmp)), Tree("new", {k: v for k, v in sys.modules.items() if _ours(k)})]
        Tree.active = trees[1]
        warm = designs(n)
        for tree in trees:  # compile or load; every per-design cache of ``warm`` filled
            tree.mod("analysis.registry").evaluate_batch(warm, fidelity=draft)
        t = {(tree.label, k, c): [] for tree in trees for k in ("fresh", "warm") for c in ("wall", "cpu")}
        for r in range(rounds):
            fresh = designs(n, seed=1000 + r)
            for tree in (trees if r % 2 == 0 else trees[::-1]):
                reg = tree.mod("analysis.registry")
                for k, ds in (("fresh", fresh), ("warm", warm)):
                    t0, c0 = time.perf_counter(), time.process_time()
                    reg.evaluate_batch(ds, fidelity=draft)
                    t[tree.label, k, "wall"].append((time.perf_counter() - t0) / n)
                    t[tree.label, k, "cpu"].append((time.process_time() - c0) / n)
        med = {k: statistics.median(v) for k, v in t.items()}
        old, new = trees[0].label, trees[1].label
        print(f"{n} designs, {rounds} rounds, medians [ms/design]")
        for k in ("fresh", "warm"):
            for c in ("wall", "cpu"):
                print(f"{k:6s} {c:4s} {old}: {1e3 * med[old, k, c]:8.3f}   {new}: {1e3 * med[new, k, c]:8.3f}   "
                      f"old/new {med[old, k, c] / med[new, k, c]:5.2f}")
    print(f"load average after {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 1024, int(sys.argv[3]) if len(sys.argv) > 3 else 5)
