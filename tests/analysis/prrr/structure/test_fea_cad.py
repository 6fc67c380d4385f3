"""CAD solid FEA (bonded pins): mesh topology and the frame-vs-FEA acceptance (one coarse solve).

One coarse mesh of prrr-paper's posed CAD parts: pins in every revolute joint, rail-slot
supports found, and the fragment makes one conformal body (every part connected through pins).
"""

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from hapticopt.analysis.prrr.structure import fea_cad
from hapticopt.design import io

pytestmark = pytest.mark.slow  # 224 s measured at load average 14 (2 cores shared): CAD build, coarse meshes, FEA at levels 2 and 0


@pytest.fixture(scope="module")
def cad():
    return fea_cad.cad_mesh(io.load_preset("prrr-paper"), size=0.03)


def test_every_revolute_joint_has_a_pin(cad):
    mesh, info = cad
    assert info["n_pins"] == 9  # 3 legs × (R1, R2, R3)
    for i in (1, 2, 3):
        for joint in ("r1", "r2", "r3"):
            assert mesh.node_sets[f"pin_{joint}_{i}"].size > 0
        for part in ("carriage", "link1", "link2"):
            assert mesh.node_sets[f"{part}_{i}"].size > 0
        assert mesh.node_sets[f"support_leg{i}"].size > 0
    assert mesh.node_sets["platform"].size > 0


def test_pins_bond_the_parts_into_one_conformal_body(cad):
    mesh, _ = cad
    t = mesh.tets
    rows = np.concatenate([t[a] for a in range(4) for b in range(4) if a != b])
    cols = np.concatenate([t[b] for a in range(4) for b in range(4) if a != b])
    n = mesh.points.shape[1]
    graph = coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    count, _ = connected_components(graph, directed=False)
    assert count == 1
    # a pin shares nodes with both parts of its joint (the bore surfaces are merged)
    pin = set(mesh.node_sets["pin_r2_1"].tolist())
    assert pin & set(mesh.node_sets["link1_1"].tolist()) and pin & set(mesh.node_sets["link2_1"].tolist())


def test_supports_are_the_rail_slot_faces(cad):
    # the clamped nodes lie on the slot boundary of carriage 1: |x_loc − r_p| or |y_loc| = slot
    mesh, info = cad
    d = io.load_preset("prrr-paper")
    from hapticopt.design.prrr import cad as cad_prrr

    L = cad_prrr.layout(d)
    T = cad_prrr.part_frames(d, info["pose"])["carriage_1"]
    loc = (mesh.points[:, mesh.node_sets["support_leg1"]].T - T[:3, 3]) @ T[:3, :3]
    edge = np.maximum(np.abs(loc[:, 0] - d.geometry.r_p), np.abs(loc[:, 1]))
    np.testing.assert_allclose(edge, L.slot, atol=1e-6)


LEGACY_CARRIAGE = ["geometry.theta_1p_deg=0", "geometry.r_p_mm=100", "structure.rail_width_mm=20",
                   "structure.carriage_wall_mm=8", "structure.carriage_height_mm=50", "structure.sea_envelope_mm=25"]


def test_frame_matches_cad_fea_within_15_percent_for_the_issue_15_carriage():
    # prrr-paper's issue-15 carriage with the R1 bracket in the clevis layer, its root plate let into the
    # block face (docs/cad.md "R1 bracket"), the frame carrying R1 on it (frame_params._brackets_many).
    # Measured (docs/structure.md "R1 bracket"): CAD FEA levels 0–4: 540.1, 530.7, 513.7, 509.6, 510.0 N/mm
    # in x (level 3 → 4: +0.1 %); level 2 here: 513.7, 514.5, 736.5 N/mm, frame 566.9, 566.9, 776.0 N/mm:
    # +10.4 %, +10.2 %, +5.4 % (+11.2, +11.2, +6.4 % at level 4). The bounding-box root before: +12.2,
    # +12.0, +7.7 % at level 4; the corner-bonded bar before that: +35/+36/+45 % at level 0.
    from hapticopt.analysis.prrr.structure import frame_model as fm
    from hapticopt.analysis.prrr.structure.stiffness import structural_stiffness
    from hapticopt.design.prrr.cad import DEFAULT_BRANCH

    d = io.load_preset("prrr-paper")
    r = fea_cad.cad_fea(d, level=2)
    frame = structural_stiffness(d, options=fm.FrameOptions(joints=fm.Joints.BONDED, branch=DEFAULT_BRANCH))
    np.testing.assert_allclose(frame.stiffness_load, r.stiffness_load, rtol=0.15)


def test_frame_matches_cad_fea_within_15_percent():
    # acceptance "frame vs FEA within 15 % per axis" on the CAD geometry (bonded 8 mm pins): the
    # default frame (pins as bonded necks, R1 on the CAD's L bracket, not tuned to the FEA) at the
    # CAD's branch with bonded joints
    from hapticopt.analysis.prrr.structure import frame_model as fm
    from hapticopt.analysis.prrr.structure.stiffness import structural_stiffness
    from hapticopt.design.prrr.cad import DEFAULT_BRANCH

    # on the carriage layout before issue 15 (rails on u_i at r_p = 100 mm, the old carriage sizes): its
    # clevis is 70 mm off the block, so the L bracket has an 80 mm root plate and a 56 mm arm. Measured
    # at level 0 (docs/structure.md "R1 bracket"): FEA 489.5, 488.7, 645.5 N/mm, frame 522.4, 522.4,
    # 667.9 N/mm: +6.7 %, +6.9 %, +3.5 % (before the bracket fix: +10.6 %, +10.9 %, +9.8 % against
    # that layout's corner-bonded CAD); for prrr-paper see the test above
    d = io.apply_overrides(io.load_preset("prrr-paper"), LEGACY_CARRIAGE)
    r = fea_cad.cad_fea(d, level=0, keep_fields=True)
    frame = structural_stiffness(d, options=fm.FrameOptions(joints=fm.Joints.BONDED, branch=DEFAULT_BRANCH))
    np.testing.assert_allclose(frame.stiffness_load, r.stiffness_load, rtol=0.15)
    assert r.stiffness_load[0] == pytest.approx(r.stiffness_load[1], rel=0.02)  # 3-fold symmetry, mesh noise
    # z stiffer than x (seed 002 Table 3: several times on the paper's device; here the legacy bracket's
    # 10 mm root plate bends under z: FEA 1.32×, frame 1.28×, measured; prrr-paper: 1.45×)
    assert r.stiffness_load[2] > 1.2 * r.stiffness_load[0]
    # the stress metric of `evaluate --fidelity fine`: the hot spot of a 1 N lateral load is a pin
    # (the 8 mm neck across a clearance gap; docs/structure_stress.md: R3 pin neck at level 2)
    from hapticopt.analysis.prrr.structure.stiffness import fea_element_stress

    stress = fea_element_stress(d, r)
    assert np.isfinite(stress.max_von_mises) and stress.max_von_mises > 0
    corners = set(r.mesh.tets[:, stress.max_element].tolist())
    pins = [name for name, nodes in r.mesh.node_sets.items() if name.startswith("pin_")]
    assert len(pins) == 9 and any(corners <= set(r.mesh.node_sets[name].tolist()) for name in pins)
