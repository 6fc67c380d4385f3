"""hapticopt.analysis.prrr.loop.zwidth: the batched Z-width map and the bisected boundary."""

from __future__ import annotations

import dataclasses

import numpy as np

from hapticopt.analysis.loop.scene import Effect, ZWidthSettings, load_scene
from hapticopt.analysis.prrr.loop.zwidth import StabilityProbe, bisect_boundary, zwidth_map


def test_map_is_monotone_in_stiffness(prrr_paper):
    sc = dataclasses.replace(load_scene("z-width"), duration=0.5,
                             zwidth=ZWidthSettings(axis=0, stiffness_range=(2e3, 60e3), damping_range=(0.0, 40.0),
                                                   points=5))
    zw = zwidth_map(prrr_paper, sc)
    assert zw.stable.shape == (5, 5)
    assert zw.stable[:, 0].all()  # 2 N/mm is far inside k_x/2
    assert not zw.stable[:, -1].any()  # 60 N/mm is beyond the eq 14 limit k_x = 28 N/mm
    # stable region is an interval in K for every B (no stable point right of an unstable one)
    for row in zw.stable:
        assert not np.any(row[1:] & ~row[:-1])
    assert set(zw.metrics()) >= {"zwidth_stable", "zwidth_stiffness_N_per_mm"}


def test_bisection_finds_sampled_wall_boundary(prrr_paper, sampled_wall):
    """Rigid transmission, no quantisation: boundary vs the exact z-domain one (as in test_stability)."""
    d = dataclasses.replace(prrr_paper, actuator=dataclasses.replace(prrr_paper.actuator, viscous=400.0))
    base = load_scene("z-width")
    sc = dataclasses.replace(base, duration=2.0,
                             effects=base.effects - {Effect.SEA_COMPLIANCE, Effect.QUANTIZATION, Effect.SATURATION})
    Bs = np.array([0.0, 100.0])
    K = bisect_boundary(StabilityProbe(d, sc), Bs, 1e4, 1e7, iters=14)
    exact = [sampled_wall.sampled_wall_boundary(mass=0.66 + 81.736 / 2, damping=200.0, virtual_damping=b, T=1e-3) for b in Bs]
    assert np.allclose(K, exact, rtol=0.02)
