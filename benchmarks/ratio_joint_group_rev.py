"""The batched draft evaluator's joint group and its result step (``joint_limits``) of this tree against
an older revision, side by side in one process (interleaved rounds, medians):
``python benchmarks/ratio_joint_group_rev.py REV [n [rounds]]`` (default 1024 designs of
``bench_batched_draft.designs``, 7 rounds).

The older revision's ``analysis/prrr/draft_batch.py`` and ``analysis/prrr/joint_limits.py`` are loaded
from ``git show REV:…`` (the old draft_batch reads the old joint_limits); every other module is this
tree's. Each round times, per tree, the core's joint group alone (``stack_inputs`` + ``run_core`` with
the groups ``("joint",)``: the jitted IK and whatever leaves XLA) and then the group plus the
joint-limit results of every design (the old tree's ``from_angles_many`` of the angles, this tree's
``from_ranges_many`` of the reductions). Prints ms per design, the ratios old / new, the load average,
and whether the two trees' results agree (statuses and messages equal, ranges and margins to 1e-12
relative).
"""

from __future__ import annotations

import math
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from revisions import module_from  # noqa: E402
from bench_batched_draft import designs  # noqa: E402

from hapticopt.analysis.fidelity import Fidelity  # noqa: E402
from hapticopt.analysis.prrr import draft_batch as DB  # noqa: E402
from hapticopt.analysis.prrr import joint_limits as JL  # noqa: E402

GROUPS = ("joint",)


def old_modules(rev: str):
    jl = module_from(rev, "analysis/prrr/joint_limits.py", "old_joint_limits")
    db = module_from(rev, "analysis/prrr/draft_batch.py", "old_draft_batch", JL=jl)
    return db, jl


def old_step(db, jl, ds, results: bool):
    out = db.run_core(db.stack_inputs(ds, None, GROUPS), len(ds), GROUPS)
    if results:
        return jl.from_angles_many(ds, out["joint_theta"], out["joint_ok"], fidelity=Fidelity.DRAFT, t0=0.0)
    return out


def new_step(ds, results: bool):
    out = DB.run_core(DB.stack_inputs(ds, None, GROUPS), len(ds), GROUPS)
    if results:
        return JL.from_ranges_many(ds, out["joint"], n_points=JL.grid_size(), fidelity=Fidelity.DRAFT, t0=0.0)
    return out


def agree(a, b) -> bool:
    def close(x, y):
        return x == y or abs(x - y) <= 1e-12 * abs(y) or (math.isnan(x) and math.isnan(y))

    return all((p.status, p.message) == (q.status, q.message) and p.used.keys() == q.used.keys()
               and all(close(u, v) for j in q.used for u, v in zip(p.used[j], q.used[j])) and close(p.margin, q.margin)
               for p, q in zip(a, b, strict=True))


def main(rev: str, n: int, rounds: int) -> None:
    print(f"load average before {' '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)
    db, jl = old_modules(rev)
    ds = designs(n)
    ref, got = old_step(db, jl, ds, True), new_step(ds, True)  # compile or load both
    t = {(tree, k): [] for tree in ("old", "new") for k in ("group", "group + results")}
    for _ in range(rounds):
        for k, results in (("group", False), ("group + results", True)):
            t0 = time.perf_counter()
            old_step(db, jl, ds, results)
            t["old", k].append((time.perf_counter() - t0) / n)
            t0 = time.perf_counter()
            new_step(ds, results)
            t["new", k].append((time.perf_counter() - t0) / n)
    med = {k: statistics.median(v) for k, v in t.items()}
    print(f"{n} designs, {rounds} rounds, medians [ms/design]; results agree: {agree(got, ref)}")
    for k in ("group", "group + results"):
        print(f"{k:16s} old {rev}: {1e3 * med['old', k]:8.4f}   new: {1e3 * med['new', k]:8.4f}   "
              f"old/new {med['old', k] / med['new', k]:5.2f}")
    print(f"load average after {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 1024, int(sys.argv[3]) if len(sys.argv) > 3 else 7)
