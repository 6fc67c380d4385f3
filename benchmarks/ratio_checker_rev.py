"""The batched draft evaluator with this tree's collision checker (``draft_batch._Checker``: pose IK,
part frames, check) against an older revision's checker, side by side in one process (interleaved
rounds in alternating order, medians; the load average printed before and after): ``python benchmarks/ratio_checker_rev.py
REV [n [rounds]]`` (default 1024 designs of ``bench_batched_draft.designs``, 3 rounds).

The older revision's ``analysis/prrr/draft_batch.py`` is loaded from ``git show REV:…`` and only its
``_Checker`` class is used (it calls this tree's ``interference_fast.check_posed``); every other step of
the batch is this tree's, so the ratio is the checker's alone. The older ``_Checker`` runs this tree's
``interference_fast`` and kernels too: since ``deepest_joints`` this compares the checkers' glue only;
``ratio_checker_kernels_rev.py`` compares the older kernels as well. Both batches' results are compared first
(equal statuses; metrics within 1e-9 relative, NaN where NaN; how many are not bit for bit equal is printed). Prints designs/s, the checker's ms per design (its calls
timed inside the batch) and the ratios old / new.
"""

from __future__ import annotations

import os
import statistics
import sys
import time

import numpy as np
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from revisions import module_from  # noqa: E402
from bench_batched_draft import designs  # noqa: E402

from hapticopt.analysis.fidelity import Fidelity  # noqa: E402
from hapticopt.analysis.prrr import draft_batch as DB  # noqa: E402
from hapticopt.analysis.registry import evaluate_batch  # noqa: E402



def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main(rev: str, n: int, rounds: int) -> None:
    print(f"load average {_load()}")
    old = module_from(rev, "analysis/prrr/draft_batch.py", "old_draft_batch")
    checkers = {"old": old._Checker, "new": DB._Checker}
    spent = {"old": 0.0, "new": 0.0}

    def timed(cls, key):
        class Timed(cls):
            def __call__(self, owner, pts):
                t0 = time.perf_counter()
                try:
                    return super().__call__(owner, pts)
                finally:
                    spent[key] += time.perf_counter() - t0
        return Timed

    ds = designs(n)
    results = {}
    for key, cls in checkers.items():  # compile / load, and compare the results
        DB._Checker = timed(cls, key)
        results[key] = evaluate_batch(ds, fidelity=Fidelity.DRAFT)
    differ, worst = 0, 0.0
    for a, b in zip(results["old"], results["new"], strict=True):
        assert a.statuses == b.statuses
        ma, mb = a.metrics(), b.metrics()
        assert list(ma) == list(mb)
        for k in ma:
            x, y = np.asarray(ma[k], dtype=float), np.asarray(mb[k], dtype=float)
            same = np.array_equal(x, y, equal_nan=True)
            differ += not same
            if not same:
                worst = max(worst, float(np.nanmax(np.abs(x - y) / np.maximum(np.abs(x), 1e-300))))
    # exactly equal where both checkers compute the same values; a checker whose pose IK follows other
    # operations (the jax IK before the numba one) may differ at rounding level: test_draft_batch's 1e-9
    assert worst <= 1e-9, worst
    print(f"results: statuses equal; {differ} metrics not bit for bit equal, largest relative difference {worst:.2e}")
    t = {k: [] for k in checkers}
    c = {k: [] for k in checkers}
    for r in range(rounds):  # the order alternates: a step right after a jitted jax call can run slower
        for key, cls in (list(checkers.items()) if r % 2 == 0 else list(checkers.items())[::-1]):
            DB._Checker = timed(cls, key)
            spent[key] = 0.0
            t0 = time.perf_counter()
            evaluate_batch(ds, fidelity=Fidelity.DRAFT)
            t[key].append((time.perf_counter() - t0) / n)
            c[key].append(spent[key] / n)
    DB._Checker = checkers["new"]
    m = {k: statistics.median(v) for k, v in t.items()}
    mc = {k: statistics.median(v) for k, v in c.items()}
    print(f"{n} designs, rev {rev}, {rounds} rounds (medians)")
    for key in checkers:
        print(f"{key} checker: batch {1 / m[key]:.1f} designs/s, checker {1e3 * mc[key]:.3f} ms/design")
    print(f"batch old/new time {m['old'] / m['new']:.2f}x; checker old/new {mc['old'] / mc['new']:.2f}x")
    print(f"load average {_load()}")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 1024, int(sys.argv[3]) if len(sys.argv) > 3 else 3)
