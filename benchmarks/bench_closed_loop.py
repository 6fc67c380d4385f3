"""Closed-loop speed (issue 6 targets: a 3 s scene at 1 kHz on the lumped plant ≥ 200× real time,
i.e. ≤ 15 ms; a 20 × 20 Z-width map ≤ 30 s). Also: per-tick controller cost and each effect's cost.

Run with ``make bench``; figures are in docs/closed_loop.md (2-core machine).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from hapticopt.analysis.prrr import closed_loop as cl
from hapticopt.analysis.prrr import firmware as fw
from hapticopt.analysis.loop.scene import Effect, load_scene
from hapticopt.analysis.prrr.zwidth import zwidth_map
from hapticopt.design import io


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


def test_controller_per_tick_scan(benchmark, paper):
    """The control law alone, compiled, 3000 ticks of recorded sensor values (per tick = time / 3000)."""
    sc = load_scene("stiffness-25")
    st = cl.setup(paper, sc)
    cfg, g = st.cfg, st.gains
    rng = np.random.default_rng(0)
    enc = jnp.asarray(np.round(rng.normal(0, 100, (3000, 1, 3))))
    defl = jnp.asarray(np.round(rng.normal(0, 100, (3000, 1, 3))))

    @jax.jit
    def run(enc, defl):
        s0 = fw.init_state(cfg, g, enc[0])
        return jax.lax.scan(lambda s, x: fw.step(cfg, g, s, x[0], x[1])[:2], s0, (enc, defl))[1]

    jax.block_until_ready(run(enc, defl))
    out = benchmark(lambda: jax.block_until_ready(run(enc, defl)))
    assert out.shape == (3000, 1, 1, 3)


def test_controller_object_step(benchmark, paper):
    """``FirmwareController.step`` called from Python (one jit dispatch per tick)."""
    st = cl.setup(paper, load_scene("stiffness-25"))
    ctl = fw.FirmwareController(st.cfg, st.gains)
    ctl.step(np.zeros(3), np.zeros(3))
    benchmark(ctl.step, np.ones(3), np.ones(3))


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

    from hapticopt.analysis import verify

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
