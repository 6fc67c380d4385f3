"""hapticopt.analysis.prrr.loop.design_map: issue 19 acceptance — the simulated stability boundary against
the exact discrete analysis, the hard corners of the (T, K_p) plane, and the map's own consistency."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hapticopt.analysis.loop.scene import load_scene
from hapticopt.analysis.prrr.loop import design_map as dm
from hapticopt.analysis.prrr.loop import stability
from hapticopt.design.errors import InvalidInput


@pytest.mark.parametrize("T, kps", [(1e-3, [45.0, 100.0]), (0.25e-3, [500.0])])
def test_simulated_boundary_matches_exact_discrete_within_2pct(prrr_paper, T, kps):
    """Three (T, K_p) points: the K_x limit by bisection on simulated decay runs (the map's
    ``--simulate-limits`` path) vs the eigenvalues of the sampled loop (stability.sampled_stiffness_limit)."""
    sc = load_scene("free-space-x")
    sim = dm.simulated_stiffness_limits(prrr_paper, sc, period=T, force_gains=np.array(kps), axis=0)
    alpha = stability.velocity_alpha(T, sc.controller.velocity_filter)
    for kp, K_sim in zip(kps, sim):
        K_exact = stability.sampled_stiffness_limit(prrr_paper, axis=0, T=T, kp=kp, alpha=alpha)
        assert K_exact > 20e3  # a real boundary, not the collapsed force loop
        assert K_sim == pytest.approx(K_exact, rel=0.02), (T, kp)


def test_collapsed_force_loop_is_zero_in_both(prrr_paper):
    """T = 1 ms, K_p = 500: the sampled force loop itself is unstable; simulation and analysis agree on 0."""
    sc = load_scene("free-space-x")
    sim = dm.simulated_stiffness_limits(prrr_paper, sc, period=1e-3, force_gains=np.array([500.0]), axis=0, iters=2)
    assert sim[0] == 0.0
    assert stability.sampled_stiffness_limit(prrr_paper, axis=0, T=1e-3, kp=500.0) == 0.0


def test_hard_cases_give_finite_metrics_and_a_verdict(prrr_paper):
    """T at 10 µs and 10 ms, K_p at 0 and 10⁴ (issue 19): no NaN where the verdict is ok, a verdict
    everywhere, unstable runs carry NaN residuals, K_p = 0 renders nothing (K limit ∞, bandwidth 0)."""
    m = dm.design_map(prrr_paper, load_scene("free-space-x"), periods=[1e-5, 1e-2], force_gains=[0.0, 1e4],
                      duration=0.6)
    assert set(m.verdict.ravel()) <= {v.value for v in dm.Verdict}
    for i in range(2):
        for j in range(2):
            v = m.verdict[i, j]
            if v == dm.Verdict.UNSTABLE:
                assert math.isnan(m.residual[i, j])
            else:
                assert math.isfinite(m.residual[i, j]) and m.residual[i, j] > 0
    assert list(m.verdict[:, 0]) == ["no_force_loop"] * 2
    assert np.all(np.isinf(m.stiffness_limit[:, 0])) and np.all(m.bandwidth[:, 0] == 0.0)
    # 10 µs, K_p = 10⁴: stable and fast (eq 8 bandwidth at 10⁴); 10 ms, K_p = 10⁴: the sampled loop is lost
    assert m.verdict[0, 1] == "ok" and m.force_loop_stable[0, 1]
    assert m.verdict[1, 1] == "unstable" and not m.force_loop_stable[1, 1] and m.stiffness_limit[1, 1] == 0.0
    assert m.bandwidth[0, 1] == pytest.approx(stability.force_loop_bandwidth(prrr_paper, 1e4), rel=0.02)
    js = m.metrics()
    assert js["map_stiffness_limit_N_per_mm"][0][0] is None and js["map_residual_N"][1][1] is None


def test_map_verdict_agrees_with_the_exact_force_loop(prrr_paper):
    """Where the exact analysis says the sampled loop is lost (K limit 0), the simulated run is unstable,
    and where it holds, the run is stable (1 kHz: K_p 45 and 200 hold, 600 does not)."""
    m = dm.design_map(prrr_paper, load_scene("free-space-x"), periods=[1e-3], force_gains=[45.0, 200.0, 600.0],
                      duration=1.0)
    assert list(m.stable[0]) == [True, True, False]
    assert list(m.stiffness_limit[0] > 0) == [True, True, False]
    # the free-space residual falls with K_p: the viscous part is ξ v_rms / (λ²(1 + ηK_p)) (issue 19)
    assert m.residual[0, 1] < m.residual[0, 0]


@pytest.mark.parametrize("kw, match", [
    ({"periods": [0.0], "force_gains": [45.0]}, "period_ms = 0 is out of range"),
    ({"periods": [1e-3], "force_gains": [-1.0]}, "force_gain = -1 is out of range"),
])
def test_map_rejects_bad_axes(prrr_paper, kw, match):
    with pytest.raises(InvalidInput, match=match):
        dm.design_map(prrr_paper, load_scene("free-space-x"), **kw)


def test_map_needs_a_report(prrr_paper):
    with pytest.raises(InvalidInput, match="has no \\[report\\] quantity"):
        dm.design_map(prrr_paper, load_scene("free-space"), periods=[1e-3], force_gains=[45.0])
