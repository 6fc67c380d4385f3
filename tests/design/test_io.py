"""hapticopt.design.io: TOML load/save, presets, --set overrides and every invalid-input path."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from hapticopt.design import io
from hapticopt.design.errors import InputFileError, InvalidDesign, UnknownName


def test_presets_listed():
    assert {"prrr-paper", "master-paper"} <= set(io.preset_names())


def test_prrr_paper_is_seed_002_table_2(prrr_paper):
    g = prrr_paper.geometry
    # seed 002 Table 2 (mm, rad)
    assert g.beta == pytest.approx(math.pi / 3)
    assert (g.d1, g.d2, g.d3, g.d4, g.r4, g.b5) == pytest.approx(
        (0.030, 0.08875, 0.080, 0.080, 0.020, 0.040))
    # r_p: Table 2 gives 100 mm; the preset uses 117 mm, the smallest rail radius (1 mm steps) whose
    # φ140 × 89 mm cylinder is collision-free at draft and standard with the preset's parts
    # (docs/workspace_interference.md "Rail placement"); eq 1 does not depend on it
    assert g.r_p == pytest.approx(0.117)
    assert g.r5 == pytest.approx(0.03464, abs=5e-6)  # r5 = b5 sin β = 34.64 mm (Table 2, 2 decimals)
    assert g.stroke == pytest.approx(0.170)  # seed digest: φ140 × 89 needs L ≈ 170 mm
    a = prrr_paper.actuator
    # seed 002 Table 4
    assert (a.spring, a.motor_mass, a.viscous, a.efficiency) == pytest.approx((56270.0, 81.736, 9705.4, 0.9173))
    assert prrr_paper.end_effector.mass == pytest.approx(0.66)


@pytest.mark.parametrize("name", ["prrr-paper", "master-paper"])
def test_save_load_roundtrip(tmp_path: Path, name: str):
    design = io.load_preset(name)
    path = tmp_path / "d.toml"
    io.save_design(design, path)
    again = io.load_design(path)
    # files hold 15 significant digits (so 60° does not print as 59.99999999999999)
    for section in design.SECTIONS:
        a, b = getattr(again, section), getattr(design, section)
        for f in a.__dataclass_fields__:
            want = getattr(b, f)  # a categorical field (the material name) exactly
            assert getattr(a, f) == (want if isinstance(want, str) else pytest.approx(want, rel=1e-14, abs=0))
    assert "beta_deg = 60.0" in path.read_text() or name != "prrr-paper"


def test_overrides_use_toml_keys(prrr_paper):
    d = io.apply_overrides(prrr_paper, ["geometry.beta_deg=50", "actuator.spring_N_per_mm=10"])
    assert d.geometry.beta == pytest.approx(math.radians(50))
    assert d.actuator.spring == pytest.approx(10e3)
    assert prrr_paper.geometry.beta == pytest.approx(math.pi / 3)  # frozen original untouched


def test_designs_are_frozen(prrr_paper):
    with pytest.raises(dataclasses.FrozenInstanceError):
        prrr_paper.geometry.beta = 1.0  # type: ignore[misc]


# ------------------------------------------------------------------ invalid input, one test per path
@pytest.mark.parametrize("value", ["0", "90", "95", "-5"])
def test_beta_out_of_range(prrr_paper, value):
    with pytest.raises(InvalidDesign, match=r"geometry\.beta_deg = .* out of range: allowed 0 < beta_deg < 90 \(deg\)"):
        io.apply_overrides(prrr_paper, [f"geometry.beta_deg={value}"])


@pytest.mark.parametrize("key", ["d1_mm", "d2_mm", "d3_mm", "d4_mm", "r4_mm", "b5_mm", "stroke_mm", "r_p_mm"])
@pytest.mark.parametrize("value", ["0", "-1"])
def test_nonpositive_lengths(prrr_paper, key, value):
    with pytest.raises(InvalidDesign, match=rf"geometry\.{key} = {value} is out of range: allowed 0 < {key} ≤ 2000 \(mm\)"):
        io.apply_overrides(prrr_paper, [f"geometry.{key}={value}"])


def test_unknown_parameter(prrr_paper):
    with pytest.raises(InvalidDesign, match=r"geometry\.d9_mm is not a known parameter: allowed keys in \[geometry\]"):
        io.apply_overrides(prrr_paper, ["geometry.d9_mm=1"])


def test_unknown_section_in_file(tmp_path):
    path = tmp_path / "d.toml"
    path.write_text('name = "x"\ndevice = "prrr"\n[geometri]\nbeta_deg = 50\n')
    with pytest.raises(InvalidDesign, match=r"geometri is not a known key for a prrr design"):
        io.load_design(path)


def test_unknown_device(tmp_path):
    path = tmp_path / "d.toml"
    path.write_text('name = "x"\ndevice = "delta"\n')
    with pytest.raises(InvalidDesign, match=r"device = 'delta' is not a known device"):
        io.load_design(path)


@pytest.mark.parametrize("value", ['"sixty"', "true", "[1, 2]"])
def test_non_numeric_in_file(tmp_path, value):
    path = tmp_path / "d.toml"
    path.write_text(f'name = "x"\ndevice = "prrr"\n[geometry]\nbeta_deg = {value}\n')
    with pytest.raises(InvalidDesign, match=r"geometry\.beta_deg = .* is not a number: allowed 0 < beta_deg < 90 \(deg\)"):
        io.load_design(path)


def test_non_numeric_override(prrr_paper):
    with pytest.raises(InvalidDesign, match=r"geometry\.beta_deg = 'abc' is not a number"):
        io.apply_overrides(prrr_paper, ["geometry.beta_deg=abc"])


def test_nan_rejected(prrr_paper):
    with pytest.raises(InvalidDesign, match=r"geometry\.d3_mm = nan is not a finite number"):
        io.apply_overrides(prrr_paper, ["geometry.d3_mm=nan"])


def test_override_without_equals(prrr_paper):
    with pytest.raises(InvalidDesign, match=r"must have the form section\.key=value"):
        io.apply_overrides(prrr_paper, ["geometry.beta_deg"])


def test_missing_file(tmp_path):
    with pytest.raises(InputFileError, match=r"does not exist"):
        io.load_design(tmp_path / "nope.toml")


def test_malformed_toml(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[geometry\nbeta_deg = 60\n")
    with pytest.raises(InputFileError, match=r"is not valid TOML"):
        io.load_design(path)


def test_unknown_preset():
    with pytest.raises(UnknownName, match=r"preset 'nope' does not exist: allowed presets are .*prrr-paper"):
        io.load_preset("nope")


def test_bore_must_be_smaller_than_boss(prrr_paper):
    with pytest.raises(InvalidDesign, match=r"structure\.bore_diameter_mm = 30 must be smaller than structure\.boss_diameter_mm"):
        io.apply_overrides(prrr_paper, ["structure.bore_diameter_mm=30"])


def test_master_joint_range_order(master_paper):
    with pytest.raises(InvalidDesign, match=r"joints\.theta3_min_deg = 50 must be below joints\.theta3_max_deg"):
        io.apply_overrides(master_paper, ["joints.theta3_min_deg=50"])


def test_save_is_atomic(tmp_path, prrr_paper, monkeypatch):
    """A failure while writing leaves neither a partial target nor a temp file."""
    from hapticopt.design import atomic as atomic

    target = tmp_path / "d.toml"

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(atomic.os, "fsync", boom)
    with pytest.raises(OSError):
        io.save_design(prrr_paper, target)
    assert list(tmp_path.iterdir()) == []


def test_saved_files_get_normal_permissions(tmp_path, prrr_paper):
    """mkstemp creates 0600 files; atomic writes must give the usual umask-based mode."""
    import os
    import stat

    target = tmp_path / "d.toml"
    io.save_design(prrr_paper, target)
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask
