"""Analytic mass properties (part tables) against the CAD's volume integrals (OpenCASCADE)."""

import math

import numpy as np
import pytest

from hapticopt.design import export as design_export
from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design import io, mass_properties as mp, parts


@pytest.fixture(scope="module", params=["prrr-paper", "prrr-isotropic-slim"])
def pair(request):
    d = io.load_preset("prrr-paper")
    if request.param == "prrr-isotropic-slim":  # seed 002 Table 5 angle, other cross-sections
        d = io.apply_overrides(d, ["geometry.beta_deg=35.26", "structure.link_width_mm=14",
                                   "structure.link_thickness_mm=6", "structure.boss_diameter_mm=18",
                                   "structure.stem_diameter_mm=8"])
    return design_export.mass_properties(d), design_export.mass_properties(d, method=mp.Method.CAD)


def test_analytic_matches_cad_per_part(pair):
    # acceptance (issue 3): mass ≤ 2 %, inertia ≤ 5 % (relative Frobenius norm about the CoM)
    ana, cad = pair
    assert set(ana.parts) == set(cad.parts)
    for name in cad.parts:
        a, c = ana.parts[name], cad.parts[name]
        assert a.mass == pytest.approx(c.mass, rel=0.02), name
        assert np.linalg.norm(a.inertia - c.inertia) <= 0.05 * np.linalg.norm(c.inertia), name
        # CoM: not in the issue; our own bound, 0.5 mm (the platform's stem/arm junction is approximate)
        assert np.linalg.norm(a.com - c.com) <= 0.5e-3, name


def test_bodies_combine_with_the_parallel_axis_theorem():
    d = io.load_preset("prrr-paper")
    m = design_export.mass_properties(d)
    base = m.bodies()["base"]
    members = [p for p in m.parts.values() if p.body == "base"]
    assert len(members) == 10  # plate, 3 rails, 3 screws, 3 motors
    assert base.mass == pytest.approx(sum(p.mass for p in members), rel=1e-12)
    # z-axis inertia by hand: Σ (I_zz + m·(x² + y²)) about the common CoM (on the z axis by symmetry)
    izz = sum(p.inertia[2, 2] + p.mass * (p.com[0] ** 2 + p.com[1] ** 2) for p in members)
    assert base.com[:2] == pytest.approx([0.0, 0.0], abs=1e-12)
    assert base.inertia[2, 2] == pytest.approx(izz, rel=1e-12)


def test_primitive_closed_forms():
    # box, cylinder, sphere closed forms; cap segment with h ≥ R is a half disc (centroid 4R/3π)
    R, t = 0.012, 0.01
    vp = parts.volume_properties([parts.capseg((0, 0, 0), np.eye(3), R, 2 * R, t)])
    assert vp.volume == pytest.approx(-math.pi * R * R / 2 * t, rel=1e-12)  # OVERLAP counts negative
    assert vp.centroid[0] == pytest.approx(4 * R / (3 * math.pi), rel=1e-10)
    cyl = parts.volume_properties([parts.cylinder((0.1, 0, 0), (0, 0, 1), R, t)])
    assert cyl.inertia[2, 2] == pytest.approx(math.pi * R**2 * t * R**2 / 2, rel=1e-12)
    assert cyl.centroid == pytest.approx([0.1, 0, 0])


def test_wedge_closed_form_two_wedges_make_a_box():
    # a wedge (right triangular prism, OVERLAP) and its half-turned twin fill the a × b × t box:
    # their sum is minus the box (volume abt, centroid at the box centre, box inertia), in any frame
    a, b, t = 0.007, 0.004, 0.02
    R0 = parts.frame((1.0, 2.0, 0.5), (0.3, -0.4, 1.0))
    o = np.array([0.05, -0.02, 0.1])
    flip = R0 @ np.diag([-1.0, -1.0, 1.0])
    pair = parts.volume_properties([parts.wedge(o, R0, a, b, t), parts.wedge(o + R0 @ (a, b, 0.0), flip, a, b, t)])
    box = parts.volume_properties([parts.box(o + R0 @ (a / 2, b / 2, 0.0), R0, a, b, t)])
    assert pair.volume == pytest.approx(-box.volume, rel=1e-12)
    np.testing.assert_allclose(pair.centroid, box.centroid, rtol=0, atol=1e-15)
    np.testing.assert_allclose(pair.inertia, -box.inertia, rtol=0, atol=1e-12 * np.abs(box.inertia).max())
    one = parts.volume_properties([parts.wedge(o, R0, a, b, t)])
    assert one.volume == pytest.approx(-a * b * t / 2, rel=1e-12)
    np.testing.assert_allclose(one.centroid, o + R0 @ (a / 3, b / 3, 0.0), atol=1e-15)  # triangle centroid


def test_total_mass_is_the_order_of_the_paper_device():
    # seed 002 Table 1: 4.4 kg, the SEA modules (motor, belt, screw, spring housing) included;
    # issue 15 acceptance: within ± 15 %
    total = design_export.mass_properties(io.load_preset("prrr-paper")).total_mass
    assert total == pytest.approx(4.4, rel=0.15)


def test_json_has_parts_and_bodies():
    import json

    d = io.load_preset("prrr-paper")
    data = json.loads(design_export.mass_properties(d).to_json())
    assert set(data["parts"]) == set(cad_prrr.part_specs(d))
    assert data["bodies"]["base"]["mass_kg"] == pytest.approx(
        sum(p["mass_kg"] for p in data["parts"].values() if p["body"] == "base"))
