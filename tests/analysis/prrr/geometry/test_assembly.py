"""``analysis/prrr/geometry/assembly.py``: a 3-PRRR that cannot be assembled is never ``ok``."""

from __future__ import annotations

import math

import pytest

from hapticopt.analysis.prrr.geometry import assembly
from hapticopt.analysis.registry import EVALUATORS, evaluate_all, evaluate_batch
from hapticopt.analysis.status import Status
from hapticopt.design import io


@pytest.fixture(scope="module")
def paper():
    return io.load_preset("prrr-paper")


def test_paper_is_assemblable(paper):
    assert assembly.check(paper, with_parts=True) == ""


def test_chain_that_cannot_close_is_not_assemblable_everywhere(paper):
    # d2 = 300 mm (the case): leg i's |ρ| ≥ |b_i − d2| with b_i = t_i·(x, y) (workspace.py's
    # reach), and Σ b_i = 0 over the three legs, so some b_i ≤ 0 and that leg needs |ρ| ≥ 300 mm,
    # beyond d3 + d4 = 160 mm (prrr-paper): no pose closes the chain
    d = io.apply_overrides(paper, ["geometry.d2_mm=300"])
    why = assembly.closure(d)
    assert "does not close" in why and "|ρ| = 300 mm at the home pose" in why
    ev = evaluate_all(d, fidelity="draft")
    assert set(ev.statuses) == {e.name for e in EVALUATORS["prrr"] if "draft" not in e.on_request_at}
    assert all(s is Status.NOT_ASSEMBLABLE for s in ev.statuses.values()), ev.statuses
    m = ev.metrics()
    assert math.isnan(m["jacobian_condition"]) and math.isnan(m["max_force_N"])  # statics: no plausible numbers
    assert math.isnan(m["force_loop_bandwidth_Hz"]) and math.isnan(m["interference_removed_fraction"])


def test_reach_just_closing_is_assemblable(paper):
    # c_u = 0 puts the axis at |ρ| = d2 (seed digest); d3 + d4 = d2 + 0.4 mm reaches it, d2 − 2 mm does not
    g = paper.geometry
    cu0 = [f"geometry.b5_mm={(g.d1 / math.cos(g.beta) - g.r4) * 1e3!r}"]
    reach = io.apply_overrides(paper, cu0 + [f"geometry.d3_mm={(g.d2 / 2 + 2e-4) * 1e3!r}",
                                             f"geometry.d4_mm={(g.d2 / 2 + 2e-4) * 1e3!r}"])
    short = io.apply_overrides(paper, cu0 + [f"geometry.d3_mm={(g.d2 / 2 - 1e-3) * 1e3!r}",
                                             f"geometry.d4_mm={(g.d2 / 2 - 1e-3) * 1e3!r}"])
    assert assembly.closure(reach) == ""
    assert "does not close" in assembly.closure(short)


def test_parts_that_cannot_be_laid_out_are_named(paper):
    # θ_1p = 70°: the R1 clevis lies inside the carriage block (design.prrr.cad.layout refuses it)
    d = io.apply_overrides(paper, ["geometry.theta_1p_deg=70"])
    assert assembly.closure(d) == ""  # the kinematic chain closes ...
    why = assembly.check(d, with_parts=True)  # ... the parts do not fit
    assert why.startswith("the parts cannot be laid out:") and "theta_1p_deg" in why
    # issue 30 item 2, one rule: a device whose parts cannot be laid out does not exist, so the kinematic
    # evaluators (statics, stiffness, workspace, stability) give no number for it either
    ev = evaluate_all(d, fidelity="draft")
    assert set(ev.statuses) == {e.name for e in EVALUATORS["prrr"] if "draft" not in e.on_request_at}
    assert all(s is Status.NOT_ASSEMBLABLE for s in ev.statuses.values()), ev.statuses
    assert set(ev.messages.values()) == {why}
    m = ev.metrics()
    assert all(isinstance(v, float) and math.isnan(v) for v in m.values()), m
    assert {"jacobian_condition", "structural_stiffness_N_per_mm", "footprint_diameter_mm",
            "force_loop_bandwidth_Hz"} <= set(m)


def test_the_batch_applies_the_same_rule(paper):
    # the registry's batch sends every design that cannot be built to the single path (check_built_many)
    designs = [paper, io.apply_overrides(paper, ["geometry.theta_1p_deg=70"]),
               io.apply_overrides(paper, ["geometry.d2_mm=300"])]
    assert assembly.check_built_many(designs) == [assembly.check_built(d) for d in designs]
    assert [bool(w) for w in assembly.check_built_many(designs)] == [False, True, True]
    evs = evaluate_batch(designs, fidelity="draft")
    assert all(s is Status.OK for s in evs[0].statuses.values()), evs[0].statuses
    for ev in evs[1:]:
        assert all(s is Status.NOT_ASSEMBLABLE for s in ev.statuses.values()), ev.statuses
