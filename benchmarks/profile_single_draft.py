"""Where one design's draft evaluation spends its time (the optimiser's path: ``registry.evaluate_all``
of one 3-PRRR design at draft fidelity), in a warm process: ``python benchmarks/profile_single_draft.py
[calls [top]]`` (default 200 calls over the first :data:`N_SINGLE` designs of
``bench_batched_draft.designs``, 30 rows).

Before timing, the designs are evaluated one by one until the process has checked
``interference_fast.KERNEL_AFTER_POSES`` poses (the optimiser's steady state: the collision check's
compiled kernel in use). Prints the per-evaluator split (the registry's own ``timings_s``, medians
and means over the calls, ms; a pass without the profiler), the own time of each shared step of
``analysis.prrr.shared.DesignSteps`` inside it (mean, ms) and the cProfile of a second pass (cumulative and own time, the ``top`` rows each),
with the load average before and after.
"""

from __future__ import annotations

import cProfile
import collections
import os
import pstats
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_batched_draft import designs  # noqa: E402

from hapticopt.analysis import registry  # noqa: E402
from hapticopt.analysis.fidelity import Fidelity  # noqa: E402
from hapticopt.analysis.prrr import interference_fast  # noqa: E402
from hapticopt.analysis.prrr.shared import DesignSteps  # noqa: E402

N_SINGLE = 16


def warm(ds: list) -> None:
    """Evaluate ``ds`` one by one until the collision check's kernel is in use (and twice at least)."""
    rounds = 0
    while rounds < 2 or interference_fast._POSES_CHECKED[0] < interference_fast.KERNEL_AFTER_POSES:
        for d in ds:
            registry.evaluate_all(d, fidelity=Fidelity.DRAFT)
        rounds += 1


class StepTimer:
    """Own time [s] of each shared step of :class:`DesignSteps` (the first call, which computes it; a step
    inside another counts for itself only), summed while :attr:`on`."""

    def __init__(self) -> None:
        self.spent: collections.Counter = collections.Counter()
        self.on = False
        self._stack: list[float] = []  # time of the inner steps of each open step
        step = DesignSteps._step

        def timed(steps, design, name, fn):
            if not self.on or name in steps._done:
                return step(steps, design, name, fn)
            self._stack.append(0.0)
            t0 = time.perf_counter()
            try:
                return step(steps, design, name, fn)
            finally:
                dt = time.perf_counter() - t0
                inner = self._stack.pop()
                self.spent[name if isinstance(name, str) else name[0]] += dt - inner
                if self._stack:
                    self._stack[-1] += dt

        DesignSteps._step = timed


def main(calls: int, top: int) -> None:
    print(f"load average before {' '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)
    ds = designs(N_SINGLE)
    warm(ds)
    split: dict[str, list[float]] = collections.defaultdict(list)
    total: list[float] = []
    steps = StepTimer()
    for k in range(calls):  # the split without the profiler
        steps.on = True
        ev = registry.evaluate_all(ds[k % len(ds)], fidelity=Fidelity.DRAFT)
        steps.on = False
        for name, t in ev.timings_s.items():
            split[name].append(t)
        total.append(sum(ev.timings_s.values()))
    prof = cProfile.Profile()
    for k in range(calls):
        prof.enable()
        registry.evaluate_all(ds[k % len(ds)], fidelity=Fidelity.DRAFT)
        prof.disable()
    print(f"{calls} calls over {len(ds)} designs; per-evaluator medians [ms] (registry timings_s):")
    for name, ts in split.items():
        print(f"  {name:22s} {1e3 * statistics.median(ts):7.3f}   mean {1e3 * statistics.fmean(ts):7.3f}")
    print(f"  {'sum':22s} {1e3 * statistics.median(total):7.3f}   mean {1e3 * statistics.fmean(total):7.3f}")
    print("shared steps inside those (own time, mean over the calls [ms]; counted in the evaluator that asked first):")
    for name, t in steps.spent.most_common():
        print(f"  {name:22s} {1e3 * t / calls:7.3f}")
    st = pstats.Stats(prof)
    st.sort_stats("cumulative").print_stats(top)
    st.sort_stats("tottime").print_stats(top)
    print(f"load average after {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200, int(sys.argv[2]) if len(sys.argv) > 2 else 30)
