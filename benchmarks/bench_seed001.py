"""Seed 001 speed (issue 18 targets: policy iteration ≤ 50 ms; a 15 s two-link run ≤ 1 s).

Run: PYTHONPATH=<shim> python -m pytest -q benchmarks/bench_seed001.py --benchmark-enable
(figures in docs/seed001.md, 2-core machine). The jitted two-link scan is compiled outside the
timing (one untimed call); its compile time is reported by scripts/accuracy/accuracy_seed001.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from hapticopt.analysis.control import impedance_learning as il
from hapticopt.analysis.control import two_link as tl
from hapticopt.analysis.loop.scene import load_scene
from hapticopt.design.io import load_preset
from hapticopt.analysis.control import ioic_online as ioic
from hapticopt.analysis import verify

CFG = il.OuterLoopConfig()


@pytest.fixture(scope="module")
def data():
    a, b, _, _ = CFG.matrices()
    return il.collect_data(a, b, np.array([CFG.k0]), CFG.noise, np.array([-0.4, 0.0, 0.0]),
                           duration=CFG.t_learn, n_intervals=CFG.n_intervals,
                           substeps=CFG.substeps)


def test_policy_iteration(benchmark, data):
    """Eq 9 on 50 intervals from K_0 = [10, 4, 0.2] (target ≤ 50 ms)."""
    _, _, q, r = CFG.matrices()
    res = benchmark(il.policy_iteration, data, np.array([CFG.k0]), q, r)
    assert res.status is il.LearningStatus.OK


def test_collect_data(benchmark):
    """The 0.5 s data phase (500 RK4 steps of 1 ms with the Kronecker integrals)."""
    a, b, _, _ = CFG.matrices()
    benchmark(il.collect_data, a, b, np.array([CFG.k0]), CFG.noise, np.array([-0.4, 0.0, 0.0]),
              duration=0.5, n_intervals=50, substeps=10)


@pytest.mark.parametrize("step", [1e-3, 1e-2])
def test_two_link_15s(benchmark, step):
    """IOIC + NTSMTC on the two-link arm, 15 s (data phase, learning and the jitted scan;
    target ≤ 1 s at 1 ms)."""
    cfg = tl.TwoLinkConfig(outer=il.OuterLoopConfig(step=step))
    tl.simulate(cfg)  # compile outside the timing
    res = benchmark(tl.simulate, cfg)
    assert np.all(np.isfinite(res.e))


def test_outer_loop_15s(benchmark):
    """FIC, OIC and IOIC outer loops together, 15 s at 1 ms (numpy RK4)."""
    res = benchmark.pedantic(il.simulate_outer_loop, args=(CFG,), rounds=3, iterations=1)
    assert res.status is il.LearningStatus.OK


# ---------------------------------------------------------------------- in our devices (issue 18 item 5)
def _device(preset, scene):
    return load_preset(preset), load_scene(scene)


def test_online_learning_at_t_learn(benchmark):
    """The firmware's learning step at t_learn: eq 7's data from 500 tick samples + eq 9."""
    a, b, q, r = CFG.matrices()
    data = il.collect_data(a, b, np.array([CFG.k0]), CFG.noise, np.array([-0.4, 0.0, 0.0]),
                           duration=0.5, n_intervals=50, substeps=10)
    x, u = data.x_fine, data.u_fine[:-1]

    def learn():
        return il.policy_iteration(ioic.data_from_samples(x, u, 1e-3, 10), np.array([CFG.k0]), q, r)

    assert benchmark(learn).status is il.LearningStatus.OK


@pytest.mark.parametrize("preset,scene", [("master-paper", "master-ioic"), ("prrr-paper", "prrr-ioic")])
def test_device_ioic_scene(benchmark, preset, scene):
    """The bundled IOIC scene (6 s at 1 kHz): master IOIC + NTSMTC on MuJoCo, 3-PRRR IOIC over the
    SEA loops on the lumped plant (the master's model terms compiled outside the timing)."""

    design, sc = _device(preset, scene)
    verify.simulate(design, sc)
    res = benchmark.pedantic(verify.simulate, args=(design, sc), rounds=3, iterations=1)
    assert str(res.status) == "ok"
