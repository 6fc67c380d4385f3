"""The whole batched draft evaluation with this tree's ``draft_batch`` against an older revision's
``analysis/prrr/draft_batch.py``, side by side in one process (interleaved rounds, medians):
``python benchmarks/ratio_draft_batch_module.py REV [n] [rounds]`` (default 1024 designs of
``bench_batched_draft.designs``, 5 rounds).

Only ``draft_batch`` differs: the older revision's module is loaded from ``git show REV:…`` and put
in its place under ``registry.evaluate_batch`` (same registry rule, same single path, every other
module this tree's), so REV must be one whose registry rule is this tree's (for older revisions see
``ratio_batched_draft_rev.py``). Both batches' results are compared first (statuses equal, metrics
to 1e-9 relative). Prints ms per design, designs/s and the ratio old / new, with the load average.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
import types
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from revisions import module_from  # noqa: E402
from bench_batched_draft import designs  # noqa: E402

import hapticopt.analysis.prrr as prrr_pkg  # noqa: E402
from hapticopt.analysis import registry  # noqa: E402
from hapticopt.analysis.fidelity import Fidelity  # noqa: E402
from hapticopt.analysis.prrr import draft_batch  # noqa: E402

NAME = "hapticopt.analysis.prrr.draft_batch"


def _module_from(rev: str) -> types.ModuleType:
    return module_from(rev, "analysis/prrr/draft_batch.py", "old_draft_batch")


def _use(mod: types.ModuleType) -> None:
    sys.modules[NAME] = mod
    prrr_pkg.draft_batch = mod


def main(rev: str, n: int, rounds: int) -> None:
    old = _module_from(rev)
    ds = designs(n)

    def run(mod):
        _use(mod)
        try:
            return registry.evaluate_batch(ds, fidelity=Fidelity.DRAFT)
        finally:
            _use(draft_batch)

    a, b = run(old), run(draft_batch)  # compile / warm, and the two must agree
    for x, y in zip(a, b, strict=True):
        assert x.statuses == y.statuses and x.messages == y.messages
        mx, my = x.metrics(), y.metrics()
        assert mx.keys() == my.keys()
        for k in mx:
            u, v = np.asarray(mx[k], dtype=float), np.asarray(my[k], dtype=float)
            assert np.all((u == v) | (np.isnan(u) & np.isnan(v)) | (np.abs(u - v) <= 1e-9 * np.abs(u))), k
    t = {"old": [], "new": []}
    for _ in range(rounds):
        for k, mod in (("old", old), ("new", draft_batch)):
            t0 = time.perf_counter()
            run(mod)
            t[k].append((time.perf_counter() - t0) / n)
    med = {k: statistics.median(v) for k, v in t.items()}
    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}; {n} designs, {rounds} interleaved rounds, "
          f"draft_batch of {rev} against this tree's")
    for k, v in med.items():
        print(f"{k}: {1e3 * v:7.3f} ms/design ({1 / v:7.1f} designs/s)")
    print(f"old / new {med['old'] / med['new']:.2f}x")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 1024, int(sys.argv[3]) if len(sys.argv) > 3 else 5)
