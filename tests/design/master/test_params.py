"""Tests of hapticopt.design.master.params (the surgical-master design description) and its preset."""

from __future__ import annotations

import dataclasses

import pytest

from hapticopt.design import io
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.master.params import MasterDesign, MasterJoints


def test_preset_loads_and_round_trips(tmp_path):
    d = io.load_preset("master-paper")
    assert isinstance(d, MasterDesign)
    # preset choices documented in design/presets/master-paper.toml and docs/master.md
    assert d.geometry.upper_arm == pytest.approx(0.264) and d.geometry.forearm == pytest.approx(0.264)
    path = tmp_path / "m.toml"
    io.save_design(d, path)
    assert io.load_design(path) == d


def test_preset_equals_defaults_except_name():
    d = io.load_preset("master-paper")
    default = MasterDesign(name=d.name, description=d.description)
    for section in ("geometry", "links", "counterweights", "joints", "actuators"):
        assert getattr(d, section) == getattr(default, section), section


def test_joint_ranges_must_be_ordered():
    with pytest.raises(InvalidDesign, match="parallelogram_min_deg"):
        MasterDesign(joints=MasterJoints(parallelogram_min=2.0, parallelogram_max=1.0))
    with pytest.raises(InvalidDesign, match="theta3_min_deg"):
        MasterDesign(joints=MasterJoints(theta3_min=0.5, theta3_max=0.1))


def test_out_of_range_value_names_field_and_unit():
    d = io.load_preset("master-paper")
    with pytest.raises(InvalidDesign, match=r"counterweights.upper_mass_kg = -1 is out of range.*kg"):
        io.apply_overrides(d, ["counterweights.upper_mass_kg=-1"])
    with pytest.raises(InvalidDesign, match="geometry.upper_arm_mm"):
        dataclasses.replace(d, geometry=dataclasses.replace(d.geometry, upper_arm=0.0))
