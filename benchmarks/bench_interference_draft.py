"""Per-pose cost of the draft interference model (analysis/prrr/interference_draft.py, dense jax
over every pair) against the fast separating-axis model (analysis/prrr/interference_fast.py, numpy
with broad phases), side by side on the same designs and poses (medians of 5), and the verdict
agreement between them.

Target it serves (issue 22 item 3): the batched draft evaluator at ≥ 2,000 designs/s at batch 1024.
Usage: ``python benchmarks/bench_interference_draft.py [n_designs]``.
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from bench_batched_draft import designs  # noqa: E402

from hapticopt.analysis.prrr import interference_draft as D  # noqa: E402
from hapticopt.analysis.prrr import interference_fast as F  # noqa: E402
from hapticopt.analysis.prrr.workspace import ELBOW_BRANCH, INTERFERENCE_SAMPLING, workspace_sample_weights  # noqa: E402
from hapticopt.design.errors import InvalidDesign  # noqa: E402


def _median(fn, reps: int = 5) -> float:
    out = []
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return statistics.median(out)


def main(n: int) -> None:
    ds, geos, pts = [], [], []
    for d in designs(2 * n, seed=3):
        try:
            geos.append(D.geometry_of(d))
        except InvalidDesign:
            continue
        ds.append(d)
        pts.append(workspace_sample_weights(d, **INTERFERENCE_SAMPLING)[0])
        if len(ds) == n:
            break
    k = min(len(p) for p in pts)
    P = np.stack([p[:k] for p in pts])
    G = D.stack(geos)
    models = [F.prepare(d) for d in ds]
    D.check(G, P)  # compile
    t_draft = _median(lambda: D.check(G, P))
    t_fast = _median(lambda: [F.check_points(m, P[i], branch=ELBOW_BRANCH) for i, m in enumerate(models)])
    c = D.check(G, P)[0]
    f = np.stack([F.check_points(m, P[i], branch=ELBOW_BRANCH).collides for i, m in enumerate(models)])
    poses = len(ds) * k
    print(f"{len(ds)} designs × {k} poses: draft {t_draft / poses * 1e6:.1f} µs/pose, fast {t_fast / poses * 1e6:.1f} "
          f"µs/pose, draft/fast time ratio {t_draft / t_fast:.2f}; fast collisions missed by draft "
          f"{int(np.sum(f & ~c))}, draft-only collisions {int(np.sum(c & ~f))} of {poses} poses")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 32)
