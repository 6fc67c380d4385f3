"""The 3-PRRR part layout (:mod:`hapticopt.design.prrr.layout`): a batch of designs and each design
alone give the same tables, bit for bit, and the same refusals with the same messages.

Reference: :func:`hapticopt.design.prrr.cad.part_specs`, :func:`cad.device_height` and
:func:`cad.carriage_bracket` of each design alone (the layout's formulas without the design axis).
Designs: prrr-paper, hard cases (the R3 riser of link2, a rule at its threshold, a branch point
exactly at zero, designs each rule refuses) and a seeded sample over wide bounds (both bracket faces,
both part layouts, refused designs among them).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hapticopt.design import io
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.parts import Role
from hapticopt.design.prrr import cad, layout

BASE = io.load_preset("prrr-paper")


def _geometry(design, **kw):
    return dataclasses.replace(design, geometry=dataclasses.replace(design.geometry, **kw))


def _structure(design, **kw):
    return dataclasses.replace(design, structure=dataclasses.replace(design.structure, **kw))


def _wide_sample(n: int, seed: int) -> list:
    """Seeded designs over bounds wider than the bundled problem's (θ_1p all round, r4 and b5 free:
    both bracket faces, with and without the link2 riser, many refused by the layout's rules)."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        kw = dict(beta=math.radians(rng.uniform(30, 70)), d2=rng.uniform(0.04, 0.12), d3=rng.uniform(0.05, 0.12),
                  d4=rng.uniform(0.05, 0.12), stroke=rng.uniform(0.12, 0.22), r_p=rng.uniform(0.09, 0.14),
                  theta_1p=math.radians(rng.uniform(-180, 180)), r4=rng.uniform(0.01, 0.04),
                  b5=rng.uniform(0.02, 0.06))
        try:
            out.append(_geometry(BASE, **kw))
        except InvalidDesign:
            continue
    return out


def _hard() -> list:
    return [BASE,
            _geometry(BASE, r4=0.030),  # link2's R3 riser (r4 > 2T + 2g + MIN_FEATURE)
            _structure(BASE, clearance=cad.MIN_FEATURE),  # a wall exactly at the rule's threshold (builds)
            _structure(BASE, clearance=0.4e-3),  # a wall below it (refused)
            _structure(BASE, bore_diameter=23.5e-3),  # a boss wall too thin
            _geometry(BASE, d3=0.020),  # a link too short for its bosses
            _structure(BASE, stem_diameter=0.030),  # the handle no wider than the stem
            _geometry(BASE, theta_1p=0.0),  # the clevis axis exactly parallel to the side face's normal (w·N = 0)
            _geometry(BASE, r_p=0.010)]  # the carriage crossing the z axis


def _assert_tables_equal(designs) -> tuple[list, np.ndarray]:
    """Every design once in a group or in ``rest``; a tabled design's rows equal its tables alone bit for
    bit; a design in ``rest`` is refused alone with the message its batch row gives."""
    groups, rest = layout.part_tables_many(designs)
    seen = np.concatenate([t.index for t in groups] + [rest])
    assert sorted(seen.tolist()) == list(range(len(designs)))
    for t in groups:
        for row, i in enumerate(t.index):
            specs = cad.part_specs(designs[i])
            assert t.part_names == tuple(specs)
            assert t.bodies == tuple(s.body for s in specs.values())
            flat = [(j, p) for j, name in enumerate(t.part_names) for p in specs[name].primitives]
            assert [j for j, _ in flat] == t.prim_part.tolist()
            assert [int(p.kind) for _, p in flat] == t.kind.tolist()
            assert [p.role for _, p in flat] == list(t.role)
            for got, want in ((t.o[row], np.array([p.o for _, p in flat])),
                              (t.R[row], np.array([p.R for _, p in flat])),
                              (t.dims[row], np.array([p.dims for _, p in flat]))):
                assert got.tobytes() == want.tobytes(), designs[i].geometry
            assert t.density[row].tolist() == [s.density for s in specs.values()]
            assert float(t.height[row]) == cad.device_height(designs[i])
    L = layout.layouts(designs)
    for i in rest.tolist():
        with pytest.raises(InvalidDesign) as err:
            cad.part_specs(designs[i])
        assert str(err.value) == str(L.error(i))
    return groups, rest


def test_tables_equal_part_specs_on_the_hard_cases():
    designs = _hard()
    groups, rest = _assert_tables_equal(designs)
    tabled = {int(i) for t in groups for i in t.index}
    # prrr-paper, the riser, a wall at the threshold, θ_1p = 0 (w·N = 0 on the side face: a branch point)
    assert tabled == {0, 1, 2, 7}
    assert {len(t.kind) for t in groups} == {97, 103}  # without and with the riser (two primitives per link2)
    assert set(rest.tolist()) == {3, 4, 5, 6, 8}


def test_tables_equal_part_specs_on_a_wide_sample():
    designs = _wide_sample(300, seed=5)
    groups, rest = _assert_tables_equal(designs)
    faces = {cad.carriage_bracket(designs[i]).face for t in groups for i in t.index}
    assert "side" in faces and faces & {"front", "back"}  # both kinds of block face are covered
    assert len(groups) == 2  # both part layouts
    assert sum(len(t.index) for t in groups) >= 60
    assert len(rest) >= 60  # refusals are covered too


def test_refused_design_names_the_rule():
    d = _structure(BASE, clearance=0.4e-3)
    groups, rest = layout.part_tables_many([BASE, d])
    assert rest.tolist() == [1]
    with pytest.raises(InvalidDesign, match="structure.clearance_mm = 0.4 is too thin"):
        cad.part_specs(d)
    assert str(layout.layouts([BASE, d]).error(1)).startswith("structure.clearance_mm = 0.4 is too thin")


def test_empty_batch():
    groups, rest = layout.part_tables_many([])
    assert groups == [] and len(rest) == 0


def test_roles_and_solid_counts_follow_the_part_builders():
    (t,) = layout.part_tables_many([BASE])[0]
    solid = [r == Role.SOLID for r in t.role]
    # closed count: base 1, rails/screws/motors 9, carriage 4 SOLID (block, arm, boss, root) ×3,
    # housing 1 ×3, link1 3 (bar, 2 bosses) ×3, link2 3 ×3, platform 3 arms × 2 + stem + ball = 8
    assert sum(solid) == 1 + 9 + 12 + 3 + 9 + 9 + 8


def test_legs_share_one_primitive_tuple():
    """The parts that are the same in each leg's frame share one tuple (built and integrated once)."""
    specs = cad.part_specs(BASE)
    for name in ("carriage", "housing", "link1", "link2"):
        assert specs[f"{name}_1"].primitives is specs[f"{name}_2"].primitives is specs[f"{name}_3"].primitives
    assert specs["rail_1"].primitives is not specs["rail_2"].primitives


def _assert_brackets_equal(designs) -> np.ndarray:
    """:func:`layout.brackets_many` row by row against :func:`cad.carriage_bracket` (checked), bit for
    bit; ``rest`` holds exactly the designs it refuses (same message as the batch row's)."""
    b, rest = layout.brackets_many(designs)
    many = layout.brackets(designs)
    for i, d in enumerate(designs):
        if i in rest:
            with pytest.raises(InvalidDesign, match="no face of the carriage block") as err:
                cad.carriage_bracket(d)
            assert str(err.value) == many.message(i)
            continue
        one = cad.carriage_bracket(d)
        want = dict(clevis=one.clevis, axis=one.axis, normal=one.normal, e_l=one.e_l, arm_length=one.arm_length,
                    root_axes=one.root_axes, root_size=np.array(one.root_size), contact=one.contact_centre,
                    n_p=one.contact_axes[:, 1], contact_size=np.array(one.contact_size))
        assert set(want) <= set(b)
        for k, v in want.items():
            assert np.asarray(b[k][i]).tobytes() == np.asarray(v, dtype=float).tobytes(), (k, d.geometry)
    return rest


def test_brackets_equal_carriage_bracket_on_the_hard_cases():
    designs = _hard()
    rest = _assert_brackets_equal(designs)
    # the walls, bosses, links and stem of 3–6 are layout rules, not the bracket's; θ_1p = 0 (7) is carried
    assert len(rest) == 0


def test_brackets_equal_carriage_bracket_on_a_wide_sample():
    designs = _wide_sample(300, seed=5)
    rest = _assert_brackets_equal(designs)
    tabled = [i for i in range(len(designs)) if i not in rest]
    faces = {cad.carriage_bracket(designs[i]).face for i in tabled}
    assert "side" in faces and faces & {"front", "back"}  # both kinds of block face are covered
    assert len(tabled) >= 60 and len(rest) >= 1


def test_unchecked_bracket_is_the_side_face_where_no_face_carries_it():
    d = _geometry(BASE, beta=math.radians(5.0))  # the R1 axis nearly vertical: no face carries it
    with pytest.raises(InvalidDesign, match="no face of the carriage block can carry the R1"):
        cad.carriage_bracket(d)
    assert layout.brackets_many([BASE, d])[1].tolist() == [1]
    b = cad.carriage_bracket(d, checked=False)
    assert b.face == "side" and b.arm_length == BASE.structure.boss_diameter / 2 + BASE.structure.clearance
