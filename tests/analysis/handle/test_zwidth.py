"""analysis/handle/zwidth.py: the registry's Z-width evaluator on handle-paper."""

from __future__ import annotations

import math

import pytest

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.handle import model as hm
from hapticopt.analysis.handle import stability as hs
from hapticopt.analysis.handle import zwidth
from hapticopt.analysis.status import Status
from hapticopt.design import io


def test_zwidth_map_boundary_and_shape():
    d = io.load_preset("handle-paper")
    r = zwidth.evaluate(d, fidelity=Fidelity.STANDARD)
    m = r.metrics()
    assert r.status is Status.OK and len(m["zwidth_boundary_N_per_mm"]) == 20
    # B_e = 0 column: the exact boundary (eq 19's 2.61 N/mm with the exact hold)
    h0 = hm.from_design(d).with_(wall_damping_N_s_per_m=0.0)
    assert m["zwidth_boundary_N_per_mm"][0] == pytest.approx(hs.stiffness_limit(h0).value_N_per_mm, rel=1e-6)
    # eq (18) grows without bound in B_e; the sampled loop peaks and ends (docs/seed000.md: 354 N/mm near 400 N·s/m,
    # none stable above ≈ 1100 N·s/m)
    assert m["zwidth_peak_stiffness_N_per_mm"] == pytest.approx(353.75, rel=1e-3)
    assert m["zwidth_max_stable_damping_Ns_per_m"] == 1000.0
    assert m["zwidth_boundary_N_per_mm"][-1] is None
    assert all(e > b or math.isnan(b) for e, b in zip(r.eq18_boundary_N_per_m, r.map.boundary_N_per_m))


def test_plot_is_written(tmp_path):
    from hapticopt.analysis.handle import plots

    d = io.load_preset("handle-paper")
    out = plots.zwidth_plots(d, zwidth.evaluate(d, fidelity=Fidelity.DRAFT), tmp_path)
    assert [p.name for p in out] == ["handle-paper_zwidth.png"] and out[0].stat().st_size > 10_000
