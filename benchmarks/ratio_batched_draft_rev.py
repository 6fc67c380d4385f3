"""The batched draft evaluator and the single path of this tree against an older revision, side by
side in one process (interleaved rounds, medians): ``python benchmarks/ratio_batched_draft_rev.py REV
[n]`` (default n = 256 designs of ``bench_batched_draft.designs``).

The older revision's ``analysis/prrr/draft_batch.py`` and ``interference_fast.check_posed`` are
loaded from ``git show REV:…`` into this process (its registry rule is replayed: every design that
is not assemblable, parts included, took the single path); every other module is this tree's.
The single path is timed with either ``check_posed`` on N_SINGLE designs. Prints seconds per design
and the ratios old / new.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from revisions import module_from  # noqa: E402
from bench_batched_draft import N_SINGLE, designs  # noqa: E402

from hapticopt.analysis import registry  # noqa: E402
from hapticopt.analysis.fidelity import Fidelity  # noqa: E402
from hapticopt.analysis.prrr import assembly  # noqa: E402
from hapticopt.analysis.prrr import interference_fast as F  # noqa: E402



def main(rev: str, n: int, rounds: int = 3) -> None:
    old_fast = module_from(rev, "analysis/prrr/interference_fast.py", "old_interference_fast")
    old_batch = module_from(rev, "analysis/prrr/draft_batch.py", "old_draft_batch")
    old_batch.FAST = F  # the old batch calls F.check_posed, switched below
    new_check = F.check_posed
    ds = designs(n)
    few = ds[:N_SINGLE]

    def old_path():
        F.check_posed = old_fast.check_posed
        blocked = {i for i, d in enumerate(ds) if assembly.check(d, with_parts=True)}
        batched = iter(old_batch.evaluate_many([d for i, d in enumerate(ds) if i not in blocked]))
        for i, d in enumerate(ds):
            if i in blocked:
                registry.evaluate_all(d, fidelity=Fidelity.DRAFT)
            else:
                found, times = next(batched)
                registry._collect(Fidelity.DRAFT, registry._entries("prrr", None), lambda e: found[e.name],
                                  lambda e, _: times.get(e.name, 0.0))

    def new_path():
        F.check_posed = new_check
        registry.evaluate_batch(ds, fidelity=Fidelity.DRAFT)

    def single(fn):
        def run():
            F.check_posed = fn
            for d in few:
                registry.evaluate_all(d, fidelity=Fidelity.DRAFT)
        return run

    steps = {"old batch": old_path, "new batch": new_path,
             "old single": single(old_fast.check_posed), "new single": single(new_check)}
    for fn in steps.values():
        fn()  # compile / warm
    t = {k: [] for k in steps}
    for _ in range(rounds):
        for k, fn in steps.items():
            t0 = time.perf_counter()
            fn()
            t[k].append((time.perf_counter() - t0) / (n if "batch" in k else len(few)))
    F.check_posed = new_check
    med = {k: statistics.median(v) for k, v in t.items()}
    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}; {n} designs, rev {rev}")
    for k, v in med.items():
        print(f"{k:10s}: {1e3 * v:7.2f} ms/design ({1 / v:7.1f} designs/s)")
    print(f"batch old/new {med['old batch'] / med['new batch']:.2f}x; single old/new "
          f"{med['old single'] / med['new single']:.2f}x; new batch vs old single "
          f"{med['old single'] / med['new batch']:.2f}x; new batch vs new single {med['new single'] / med['new batch']:.2f}x")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 256)
