"""The batched draft evaluator's jitted core and its input stacking (``draft_batch.stack_inputs`` +
``draft_batch.run_core``) of this tree against an older revision, side by side in one process
(interleaved rounds, medians): ``python benchmarks/ratio_draft_core_rev.py REV [n [rounds]]``
(default 1024 designs of ``bench_batched_draft.designs``, 5 rounds).

The older revision's ``analysis/prrr/draft_batch.py``, ``frame_model.py``, ``workspace.py`` and
``design/prrr/cad.py`` are loaded from ``git show REV:…`` (the old draft_batch reads the old frame
model and workspace core, the old frame model the old ``carriage_bracket``); every other module is
this tree's. The workspace inputs are this tree's ``workspace_params`` of each design (no part
tables: the core's cost does not depend on them). Prints ms per design per step for the frame
group alone, the workspace group alone and all four groups, the ratios old / new, the load average, and the largest relative
difference between the two cores' outputs.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from revisions import module_from  # noqa: E402
from bench_batched_draft import designs  # noqa: E402

import numpy as np  # noqa: E402

from hapticopt.analysis.prrr import draft_batch  # noqa: E402
from hapticopt.analysis.prrr import workspace as WS  # noqa: E402



def _max_rel(a: dict, b: dict, prefix: str = "") -> tuple[float, str]:
    """The largest relative difference of ``a`` from ``b`` over the entries of each array above 1e-6
    of that array's largest (smaller entries of a compliance matrix are the rounding of the
    condensation, not results), and the key where it is; NaN patterns must match (else inf)."""
    worst = (0.0, "")
    for k in a:
        if isinstance(a[k], dict):
            worst = max(worst, _max_rel(a[k], b[k], f"{prefix}{k}."))
            continue
        x, y = np.asarray(a[k], dtype=float), np.asarray(b[k], dtype=float)
        if not np.array_equal(np.isnan(x), np.isnan(y)):
            return float("inf"), prefix + k
        ok = np.isfinite(x) & np.isfinite(y)
        big = ok & (np.abs(y) > 1e-6 * np.abs(np.where(ok, y, 0.0)).max(initial=0.0))
        if big.any():
            worst = max(worst, (float(np.max(np.abs(x[big] - y[big]) / np.abs(y[big]))), prefix + k))
    return worst


def main(rev: str, n: int, rounds: int) -> None:
    old_cad = module_from(rev, "design/prrr/cad.py", "old_cad")
    old_fm = module_from(rev, "analysis/prrr/frame_model.py", "old_frame_model", carriage_bracket=old_cad.carriage_bracket)
    old_ws = module_from(rev, "analysis/prrr/workspace.py", "old_workspace")
    old = module_from(rev, "analysis/prrr/draft_batch.py", "old_draft_batch", fm=old_fm, WS=old_ws)
    ds = designs(n)
    wps = [WS.workspace_params(d) for d in ds]
    sets = [("frame",), ("workspace",), tuple(draft_batch.CORE_GROUPS)]  # the groups this work changed, all four
    mods = {"old": old, "new": draft_batch}
    for groups in sets:  # compile (or load from the disk cache) outside the timed rounds
        for m in mods.values():
            m.run_core(m.stack_inputs(ds, wps, groups), n, groups)
    times = {(k, step, g): [] for k in mods for g in sets for step in ("stack", "core")}
    outs = {}
    for _ in range(rounds):
        for groups in sets:
            for k, m in mods.items():
                t0 = time.perf_counter()
                inp = m.stack_inputs(ds, wps, groups)
                t1 = time.perf_counter()
                outs[k, groups] = m.run_core(inp, n, groups)
                t2 = time.perf_counter()
                times[k, "stack", groups].append(t1 - t0)
                times[k, "core", groups].append(t2 - t1)
    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}; {n} designs, {rounds} rounds, "
          f"old = {rev}")
    for groups in sets:
        name = "+".join(groups)
        for step in ("stack", "core"):
            o, w = (statistics.median(times[k, step, groups]) / n * 1e3 for k in ("old", "new"))
            print(f"{name:28s} {step:5s} old {o:7.4f} new {w:7.4f} ms/design  old/new {o / w:5.2f}")
        o, w = (sum(statistics.median(times[k, s, groups]) for s in ("stack", "core")) / n * 1e3 for k in ("old", "new"))
        print(f"{name:28s} both  old {o:7.4f} new {w:7.4f} ms/design  old/new {o / w:5.2f}  "
              "max rel diff {:.1e} ({})".format(*_max_rel(outs["new", groups], outs["old", groups])))


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 1024, int(sys.argv[3]) if len(sys.argv) > 3 else 5)
