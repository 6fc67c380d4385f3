"""The batched draft evaluator's collision checker (``draft_batch._Checker``'s call: pose IK, joint
angles, the compiled check and its reductions) against an older revision's, side by side in one process on
the checker calls of one batch (captured, then replayed; interleaved rounds in alternating order, medians
and per-round ratios; the load average printed before and after): ``python
benchmarks/ratio_checker_kernels_rev.py REV [n [rounds]]`` (default 1024 designs of
``bench_batched_draft.designs``, 7 rounds).

The older side is the checker of the form of ``fc9af43`` (the start of the round that made
``interference_fast.deepest_joints``): ``_Checker.pose_ik`` (numba arithmetic, numpy's arccos / arctan2,
the branch's (n, 3, 3) angles), numpy's cos / sin of θ₁ and θ₁ + θ₂, the (poses × part pairs) depth array
and its two reductions, written out here, with REV's ``_interference_kernels`` module (``git show``, so
REV must have that form's kernel signatures: ``check_joint_poses`` without a column map); this tree's
checker is called as the batch calls it, the process past ``interference_fast.KERNEL_AFTER_POSES`` (so the
kernel route also for small n). Every replayed call's outputs (collides, reachable, deepest
overlap) are asserted bit for bit equal between the two and to the batch's own. ``ratio_checker_rev.py``
no longer isolates the checker: an older ``_Checker`` it loads calls this tree's kernels.
"""

from __future__ import annotations

import functools
import importlib.util
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_batched_draft import designs
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr import draft_batch as DB
from hapticopt.analysis.prrr import interference_fast as F
from hapticopt.analysis.registry import evaluate_batch

ROOT = Path(__file__).resolve().parents[1]


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def old_kernels(rev: str, folder: str):
    """REV's kernel module, from a file (numba compiles it there)."""
    path = Path(folder) / "old_interference_kernels.py"
    path.write_text(subprocess.run(["git", "show", f"{rev}:analysis/prrr/_interference_kernels.py"], cwd=ROOT,
                                   check=True, capture_output=True, text=True).stdout)
    spec = importlib.util.spec_from_file_location("old_interference_kernels", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def old_call(chk, K, owner, pts):
    """fc9af43's ``_Checker.__call__`` (kernel route) with kernels ``K``."""
    f64 = functools.partial(np.ascontiguousarray, dtype=np.float64)
    g = chk.geo
    n = len(pts)
    collides, reachable, depth = np.zeros(n, bool), np.zeros(n, bool), np.zeros(n)
    beta = g["beta"]
    sliders, rho_v, rho_t, c2, y, x = (np.empty((n, 3)) for _ in range(6))
    ok = np.empty(n, dtype=np.bool_)
    K.pose_ik_planar(np.ascontiguousarray(owner, dtype=np.int64), f64(pts), np.cos(beta), np.sin(beta),
                     np.tan(beta), *(g[f] for f in DB._KIN_FIELDS[1:]), DB._LEGS.u, DB._LEGS.t, sliders, rho_v, rho_t,
                     c2, y, x, ok)
    theta = DB._elbow_branch(np.arccos(c2), np.arctan2(rho_t, rho_v), np.arctan2(y, x))
    for local, batch, geometry, tables in chk.groups:
        sel = np.flatnonzero(local[owner] >= 0)
        if len(sel) == 0:
            continue
        o2, p2, s2, th, ok2 = local[owner[sel]], pts[sel], sliders[sel], theta[sel], ok[sel]  # check_joints' glue
        p2 = np.atleast_2d(np.asarray(p2, dtype=float))
        o2 = np.asarray(o2, dtype=int)
        s2, th = np.asarray(s2, dtype=float), np.asarray(th, dtype=float)
        ok2 = np.ascontiguousarray(ok2, dtype=np.bool_)
        dep = np.zeros((len(p2), len(batch.part_pairs)))
        th1, th12 = th[:, :, 0], th[:, :, 0] + th[:, :, 1]
        K.check_joint_poses(*tables.head, f64(s2), f64(np.cos(th1)), f64(np.sin(th1)), f64(np.cos(th12)),
                            f64(np.sin(th12)), f64(p2), np.ascontiguousarray(o2, dtype=np.int64), ok2,
                            *tables.design, *tables.tail, dep)
        collides[sel] = np.any(dep > F.DEPTH_TOL, axis=1)
        reachable[sel] = ok2
        depth[sel] = dep.max(axis=1) if dep.shape[1] else 0.0
    return collides, reachable, depth


def _bits(a) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.uint8)


def main(rev: str, n: int, rounds: int) -> None:
    print(f"load average before {_load()}", flush=True)
    cap = {}
    base = DB._Checker

    class Capture(base):
        def __init__(self, ds, models):
            super().__init__(ds, models)
            cap["checker"], cap["calls"] = self, []

        def __call__(self, owner, pts):
            out = super().__call__(owner, pts)
            cap["calls"].append((owner.copy(), pts.copy(), tuple(np.copy(o) for o in out)))
            return out

    ds = designs(n)
    evaluate_batch(ds, fidelity=Fidelity.DRAFT)  # compile or load
    # past KERNEL_AFTER_POSES whatever n: this tree's checker takes the kernel route, as the older one here does
    F._POSES_CHECKED[0] = max(F._POSES_CHECKED[0], F.KERNEL_AFTER_POSES)
    DB._Checker = Capture
    try:
        evaluate_batch(ds, fidelity=Fidelity.DRAFT)
    finally:
        DB._Checker = base
    chk, calls = cap["checker"], list(cap["calls"])
    new_call = functools.partial(base.__call__, chk)  # this tree's call, without the capture
    with tempfile.TemporaryDirectory() as tmp:
        K = old_kernels(rev, tmp)
        for owner, pts, ref in calls:
            for out in (old_call(chk, K, owner, pts), new_call(owner, pts)):
                assert all(np.array_equal(_bits(a), _bits(b)) for a, b in zip(out, ref, strict=True))
        print(f"{len(calls)} calls, {sum(len(c[0]) for c in calls)} poses: outputs bit for bit equal", flush=True)
        t = {"old": [], "new": []}
        sides = {"old": functools.partial(old_call, chk, K), "new": new_call}
        for r in range(rounds):
            for key in (("old", "new") if r % 2 == 0 else ("new", "old")):
                t0 = time.perf_counter()
                for owner, pts, _ in calls:
                    sides[key](owner, pts)
                t[key].append((time.perf_counter() - t0) / n)
    mo, mn = statistics.median(t["old"]), statistics.median(t["new"])
    ratios = sorted(o / w for o, w in zip(t["old"], t["new"]))
    print(f"{n} designs, rev {rev}, {rounds} rounds: checker {1e3 * mo:.3f} -> {1e3 * mn:.3f} ms per design "
          f"(medians), old/new {mo / mn:.2f}x; per-round ratios {' '.join(f'{x:.2f}' for x in ratios)} "
          f"(median {statistics.median(ratios):.2f})")
    print(f"load average after {_load()}")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 1024, int(sys.argv[3]) if len(sys.argv) > 3 else 7)
