"""Issue 34 benchmarks: Monte Carlo of off-nominal 3-PRRR devices and the sensitivities of one design.

Targets (2-core machine): 10,000 devices, each IK + J over ≥ 100 poses and the constancy deviation,
≤ 30 s; the sensitivities of every draft metric to every continuous key ≤ 2 s. pytest-benchmark times
them (``make bench``-style); ``python benchmarks/bench_tolerance.py`` measures each side by side with
a plain numpy loop (one device, or one design, at a time: the same kernels unbatched), interleaved
rounds, medians, and prints the ratios and the load.
"""

from __future__ import annotations

import os
import time

import numpy as np

from hapticopt.analysis import registry
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design import io
from hapticopt.design.prrr import tolerance as dtol
from hapticopt.optim import sensitivity as sens
from hapticopt.optim import tolerance as tol

DEVICES = 10_000


def _errors(n: int, seed: int = 0) -> np.ndarray:
    design = io.load_preset("prrr-paper")
    return tol.draw(tol.iso_spec(design, "m"), np.random.default_rng(seed), n)


def test_monte_carlo_10000_devices(benchmark):
    design = io.load_preset("prrr-paper")
    spec = tol.iso_spec(design, "m")
    benchmark.extra_info["poses"] = len(dtol.pose_grid())
    benchmark.pedantic(lambda: tol.monte_carlo(design, spec, samples=DEVICES, seed=0), rounds=1, iterations=1)


def test_sensitivities_all_draft_metrics(benchmark):
    design = io.load_preset("prrr-paper")
    sens.sensitivities(design)  # the batch's compile, once
    benchmark.pedantic(lambda: sens.sensitivities(design), rounds=3, iterations=1)


# ------------------------------------------------------------------- side by side with a plain loop
def _loop_devices(design, errors):
    """The plain loop: one device per call of the same kernel."""
    return [dtol.offnominal(design, errors[i:i + 1]) for i in range(len(errors))]


def _loop_sensitivities(design):
    """The plain loop: every FD design through registry.evaluate_all, one at a time (no batch, no jax)."""
    keys = sens.continuous_keys(design)
    base = registry.evaluate_all(design, fidelity=Fidelity.DRAFT)
    for key in keys:
        for rel in sens.STEPS:
            for sign in (1, -1):
                d = sens._perturbed(design, key, key.value + sign * sens._step(key, rel))
                if d is not None:
                    registry.evaluate_all(d, fidelity=Fidelity.DRAFT)
    return base


def _median_ratio(fast, slow, rounds: int) -> tuple[float, float, float]:
    tf, ts = [], []
    for _ in range(rounds):
        t0 = time.perf_counter()
        fast()
        tf.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        slow()
        ts.append(time.perf_counter() - t0)
    f, s = float(np.median(tf)), float(np.median(ts))
    return f, s, s / f


def main() -> None:
    design = io.load_preset("prrr-paper")
    print(f"load {os.getloadavg()}")
    e = _errors(64)
    dtol.offnominal(design, e[:2])
    f, s, r = _median_ratio(lambda: dtol.offnominal(design, e), lambda: _loop_devices(design, e), 3)
    print(f"Monte Carlo, 64 devices × {len(dtol.pose_grid())} poses: batched {f:.2f} s, loop {s:.2f} s, "
          f"ratio {r:.1f}x; batched {f / 64 * 1e3:.1f} ms/device → {DEVICES} devices ≈ {f / 64 * DEVICES:.0f} s")
    sens.sensitivities(design)
    _loop_sensitivities(design)
    f, s, r = _median_ratio(lambda: sens.sensitivities(design), lambda: _loop_sensitivities(design), 3)
    print(f"sensitivities, all draft metrics × {len(sens.continuous_keys(design))} keys: batched {f:.2f} s, "
          f"loop {s:.2f} s, ratio {r:.1f}x")
    print(f"load {os.getloadavg()}")


if __name__ == "__main__":
    main()
