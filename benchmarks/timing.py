"""Median wall time of a call, for the accuracy-vs-time scripts (pytest-benchmark times `bench_*.py`)."""

from __future__ import annotations

import statistics
import time


def median_wall(fn, n: int = 7, *, warm: bool = True) -> float:
    """Median of ``n`` wall times [s] of ``fn()``; one untimed call first when ``warm``."""
    if warm:
        fn()
    ts = []
    for _ in range(n):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts)
