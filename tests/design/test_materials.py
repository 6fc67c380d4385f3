"""hapticopt.design.materials: the sourced library, the design's material key and the one-line error."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from hapticopt.design import io, materials
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.prrr import cad
from hapticopt.design.prrr.params import with_material
from hapticopt.optim.cli import app

ROOT = Path(__file__).resolve().parents[2]
#: the issue's required materials (issue 32 item 1)
REQUIRED = ("6061-T6", "7075-T6", "304", "S355", "PA12-SLS", "PLA-FDM", "CFRP-tube")


def test_every_required_material_is_there_and_sourced():
    lib = materials.library()
    assert set(REQUIRED) <= set(lib)
    for m in lib.values():
        assert len(m.source) > 40 and m.process, m.name
        assert 0.0 < m.poisson_ratio < 0.5 and m.density > 0 and m.youngs_modulus > 0
        assert 0.0 < m.fatigue_strength and m.fatigue_cycles >= 1e6
        assert m.yield_strength <= m.ultimate_strength, m.name  # a proof stress above the ultimate is a typo
    # handbook values (ASM Handbook Vol. 2: 6061-T6 yield 276 MPa, E 68.9 GPa) in SI
    assert lib["6061-T6"].yield_strength == 276e6 and lib["6061-T6"].youngs_modulus == 68.9e9
    assert "ANISOTROPIC" in lib["PLA-FDM"].note and "ANISOTROPIC" in lib["CFRP-tube"].note


def test_library_is_packaged():
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "materials.toml" in data["tool"]["setuptools"]["package-data"]["hapticopt.design"]


def test_unknown_material_is_one_line_naming_field_and_known_materials():
    with pytest.raises(InvalidDesign) as exc:
        materials.material("unobtainium")
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("structure.material = 'unobtainium'")
    assert all(name in msg for name in REQUIRED)


def test_unknown_material_at_the_cli_exits_2():
    res = CliRunner().invoke(app, ["evaluate", "--preset", "prrr-paper", "--fidelity", "draft",
                                   "--set", "structure.material=unobtainium"])
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "structure.material" in lines[0] and "6061-T6" in lines[0]


def test_material_key_sets_density_and_moduli_and_round_trips(tmp_path):
    base = io.load_preset("prrr-paper")
    assert base.structure.material == "6061-T6"  # the default: the preset's numbers are 6061-T6's
    pla = io.apply_overrides(base, ["structure.material=PLA-FDM"])
    m = materials.material("PLA-FDM")
    assert (pla.structure.density, pla.structure.youngs_modulus, pla.structure.poisson_ratio) == (
        m.density, m.youngs_modulus, m.poisson_ratio)
    assert pla.structure == with_material(base, "PLA-FDM").structure
    path = tmp_path / "pla.toml"
    io.save_design(pla, path)
    assert io.load_design(path).structure == pla.structure
    # an explicit number next to the material overrides it (a custom variant of the named material)
    custom = io.apply_overrides(base, ["structure.material=PLA-FDM", "structure.density_kg_per_m3=1000"])
    assert custom.structure.density == 1000.0 and custom.structure.youngs_modulus == m.youngs_modulus


def test_parts_name_their_material_and_mass_reads_it():
    base = io.load_preset("prrr-paper")
    steel = with_material(base, "304")
    a, b = cad.part_specs(base), cad.part_specs(steel)
    for name in ("link1_1", "link2_3", "platform", "carriage_2"):
        assert a[name].material == "6061-T6" and b[name].material == "304"
        assert b[name].density / a[name].density == pytest.approx(8000.0 / 2700.0)
    assert a["motor_1"].material == "" and b["motor_1"].density == a["motor_1"].density  # catalogue part


def test_frame_stiffness_reads_the_material():
    from hapticopt.analysis.prrr.structure import stiffness as ss
    base = io.load_preset("prrr-paper")
    k0 = ss.structural_stiffness(base).stiffness_load
    # 7075-T6 has the same ν as 6061-T6: a linear-elastic frame of one material scales with E
    k1 = ss.structural_stiffness(with_material(base, "7075-T6")).stiffness_load
    np.testing.assert_allclose(k1 / k0, 71.7 / 68.9, rtol=1e-9)
