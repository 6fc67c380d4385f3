"""Closed-loop speed (targets: a 3 s scene at 1 kHz on the lumped plant ≥ 200× real time,
i.e. ≤ 15 ms; a 20 × 20 Z-width map ≤ 30 s). Also each effect's cost, and a repeated `verify.simulate` against its compiled run.

Run with ``make bench``; figures are in docs/closed_loop.md (2-core machine).
"""

from __future__ import annotations

import dataclasses

import pytest

from hapticopt.analysis.prrr.loop import closed_loop as cl
from hapticopt.analysis.loop.scene import Effect, load_scene
from hapticopt.analysis.prrr.loop.zwidth import zwidth_map
from hapticopt.design import io
from hapticopt.analysis import verify


@pytest.fixture(scope="module")
def paper():
    return io.load_preset("prrr-paper")


def _sim(paper, scene):
    st = cl.setup(paper, scene)
    sim = cl.Simulator(st)
    sim.run()  # compile outside the timing
    return sim


@pytest.mark.parametrize("scene", ["stiffness-25", "free-space", "virtual-box"])
def test_scene_3s_lumped(benchmark, paper, scene):
    sim = _sim(paper, load_scene(scene))
    tr = benchmark(sim.run)
    assert tr.energy.shape[0] == 3000


ALL = load_scene("stiffness-25").effects


@pytest.mark.parametrize("off", ["none"] + sorted(e.value for e in ALL))
def test_effect_cost(benchmark, paper, off):
    """Each effect switched off in turn from the full stiffness-25 scene (the difference is its cost)."""
    sc = load_scene("stiffness-25")
    if off != "none":
        sc = dataclasses.replace(sc, effects=sc.effects - {Effect(off)})
    sim = _sim(paper, sc)
    benchmark(sim.run)


def test_zwidth_map_20x20(benchmark, paper):
    sc = load_scene("z-width")
    zw = benchmark.pedantic(zwidth_map, args=(paper, sc), rounds=1, iterations=1)
    assert zw.stable.shape == (20, 20) and zw.stable.any() and not zw.stable.all()


@pytest.mark.parametrize("scene", ["stiffness-25", "free-space", "virtual-box"])
def test_repeated_simulate_vs_compiled_run(benchmark, paper, scene):
    """Issue 22 target: a repeated ``verify.simulate`` of a lumped scene (setup, plant matrices, the loop
    compiled once per structure, metrics) ≤ 1.3× the compiled run alone; interleaved medians of 7."""
    import os
    import statistics
    import time


    sc = load_scene(scene)
    sim = _sim(paper, sc)
    verify.simulate(paper, sc)
    traced = cl.TRACE_COUNT["chunk"]
    full, run = [], []

    def both():
        t = time.perf_counter()
        verify.simulate(paper, sc)
        full.append(time.perf_counter() - t)
        t = time.perf_counter()
        sim.run()
        run.append(time.perf_counter() - t)

    benchmark.pedantic(both, rounds=7, iterations=1)
    ratio = statistics.median(full) / statistics.median(run)
    benchmark.extra_info.update(simulate_s=statistics.median(full), run_s=statistics.median(run), ratio=ratio,
                                load_average=os.getloadavg()[0])
    assert cl.TRACE_COUNT["chunk"] == traced  # nothing retraced
    assert ratio <= 1.3
