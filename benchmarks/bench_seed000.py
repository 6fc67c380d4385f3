"""Seed 000 handle + upsampling benchmarks (issue 17), 2-core CPU shared with others.

Targets: exact stability boundary of the handle ≤ 1 ms; Z-width map 20 × 20 ≤ 2 s; the firmware's
predictor (online AR(2) fit over 16 samples) + spline (l2/l1 = 4) per update, reported.
BLAS is pinned to one thread (pitfalls: OpenBLAS threads spin against each other on 2 cores).

Run: PYTHONPATH=<shim> .venv/bin/python -m pytest benchmarks/bench_seed000.py --benchmark-enable
"""

from __future__ import annotations

import numpy as np
import pytest
from hapticopt.analysis.control import upsampling as up
from hapticopt.analysis.handle import model as hm
from hapticopt.analysis.handle import stability as hs
from threadpoolctl import threadpool_limits
from hapticopt.design import io
from hapticopt.analysis.registry import EVALUATORS
from hapticopt.analysis import verify
from hapticopt.analysis.loop.scene import load_scene
from hapticopt.analysis.handle.firmware import HandleFirmware, HandleFirmwareConfig, WallKind, WallLaw
from hapticopt.analysis.prrr.loop import multirate as mr
H = hm.HANDLE_PAPER


@pytest.fixture(autouse=True)
def _one_blas_thread():
    with threadpool_limits(1):
        yield


def test_exact_boundary(benchmark):
    lim = benchmark(hs.stiffness_limit, H)
    assert lim.status is hs.LimitStatus.OK
    assert benchmark.stats is None or benchmark.stats.stats.median <= 1e-3  # target ≤ 1 ms


def test_zwidth_map_20x20(benchmark):
    B = np.linspace(0.0, 1900.0, 20)
    K = np.geomspace(1e2, 1e6, 20)
    z = benchmark.pedantic(hs.zwidth_map, args=(H, B, K), rounds=5, iterations=1)
    assert z.margin.shape == (20, 20)
    assert benchmark.stats is None or benchmark.stats.stats.median <= 2.0  # target ≤ 2 s


@pytest.mark.parametrize("online", [True, False], ids=["online-AR2-fit", "fixed-coefficients"])
def test_firmware_tick(benchmark, online):
    f = up.Firmware(period_s=1e-3, upsampling=4, variant=up.DEFAULT_VARIANT, order=2, window=16,
                    coefficients=None if online else np.array([2.0, -1.0]))
    x = 1e-3 * np.sin(0.07 * np.arange(32))
    tick = benchmark(up.firmware_tick, f, 5e3, x, [1.0, 1.1])
    assert tick.forces_N.shape == (4,) and np.all(np.isfinite(tick.forces_N))


def test_lifted_limit_as_intended(benchmark):
    f = up.Firmware(period_s=1e-3, upsampling=4, variant=up.Variant.AS_INTENDED, coefficients=np.array([2.0, -1.0]))
    lim = benchmark(up.lifted_stiffness_limit, hm.wall_plant(H), f, reference_N_per_m=2.6e3)
    assert lim.status == "ok"


# ------------------------------------------------------------------ the handle device (registry evaluators)
@pytest.fixture(scope="module")
def handle_paper():
    return io.load_preset("handle-paper")


@pytest.mark.parametrize("name", ["stability", "upsampling", "zwidth"])
def test_handle_evaluator(benchmark, handle_paper, name):
    entry = next(e for e in EVALUATORS["handle"] if e.name == name)
    mod = entry.load()
    r = benchmark.pedantic(mod.evaluate, args=(handle_paper,), rounds=5, iterations=1)
    assert str(r.status) == "ok"


@pytest.mark.parametrize("scene", ["handle-wall", "handle-ball"])
def test_handle_scene(benchmark, handle_paper, scene):
    sc = load_scene(scene)
    r = benchmark.pedantic(verify.simulate, args=(handle_paper, sc), rounds=3, iterations=1)
    assert r.stable


def test_handle_firmware_step(benchmark):
    cfg = HandleFirmwareConfig(period_s=1e-3, upsampling=4, variant=up.DEFAULT_VARIANT, ar_coefficients=(2.0, -1.0),
                               wall=WallLaw(kind=WallKind.ONE_SIDED, stiffness_N_per_m=3e3, damping_N_s_per_m=0.0,
                                            half_width_m=5e-3))
    ctl = HandleFirmware(cfg)
    ctl.reset(5.5e-3)
    out = benchmark(ctl.step, 5.6e-3)
    assert out.shape == (4,)


# ------------------------------------------------------------------ the 3-PRRR's lifted loop
@pytest.mark.parametrize("L", [1, 4])
def test_prrr_lifted_limit(benchmark, L):
    d = io.load_preset("prrr-paper")
    s = mr.LoopSettings(upsampling=L, variant=up.DEFAULT_VARIANT)
    lim = benchmark.pedantic(mr.stiffness_limit, args=(d, s), rounds=5, iterations=1)
    assert lim.status == "ok"
