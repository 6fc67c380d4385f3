"""design/handle/params.py and the handle-paper preset: seed 000's values in SI, ranges, one-line errors."""

from __future__ import annotations

import pytest

from hapticopt.design import io
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.handle.params import HandleDesign


def test_preset_is_the_papers_handle_in_si():
    d = io.load_preset("handle-paper")
    assert isinstance(d, HandleDesign) and d.device == "handle"
    # seed 000 section 2.2: r = 6 mm, R = 150 mm, I_m = 34.7 g·cm², I_l = 4593.75 g·cm², B_m = 11.72 g·cm²/ms;
    # 1 g·cm² = 1e-7 kg·m², 1 g·cm²/ms = 1e-4 N·m·s/rad
    assert d.geometry.motor_radius == pytest.approx(6e-3, rel=1e-15)
    assert d.geometry.lever == pytest.approx(0.15, rel=1e-15)
    assert d.drive.motor_inertia == pytest.approx(3.47e-6, rel=1e-14)
    assert d.drive.link_inertia == pytest.approx(4.59375e-4, rel=1e-14)
    assert d.drive.motor_damping == pytest.approx(1.172e-3, rel=1e-14)
    assert d.firmware.period == pytest.approx(1e-3, rel=1e-15)
    # B_e = 30 "g·cm²/s" of eq (19) is 30 g/s = 0.030 N·s/m (docs/seed000.md)
    assert d.wall.damping == pytest.approx(0.030, rel=1e-15)
    assert d.operator.stiffness == 0.0


def test_round_trip_through_toml(tmp_path):
    d = io.load_preset("handle-paper")
    p = tmp_path / "h.toml"
    io.save_design(d, p)
    assert io.load_design(p) == d


@pytest.mark.parametrize("override, match", [
    ("drive.motor_inertia_g_cm2=-3", r"^drive\.motor_inertia_g_cm2 = -3 is out of range: allowed 0 < motor_inertia_g_cm2 ≤ 1e\+09 \(g·cm²\)$"),
    ("firmware.upsampling=2.5", r"^firmware\.upsampling = 2\.5 must be a whole number: allowed 1 ≤ upsampling ≤ 64 \(-\)$"),
    ("firmware.ar_window=3", r"^firmware\.ar_window = 3 is out of range: allowed ≥ 2·firmware\.ar_order = 4 \(samples;"),
    ("drive.motor_damping_g_cm2_per_ms=0", r"^drive\.motor_damping_g_cm2_per_ms = 0 is out of range: allowed 0 < "
                                           r"motor_damping_g_cm2_per_ms ≤ 1e\+09 \(g·cm²/ms\)$"),
])
def test_bad_values_are_one_line(override, match):
    with pytest.raises(InvalidDesign, match=match) as exc:
        io.apply_overrides(io.load_preset("handle-paper"), [override])
    assert "\n" not in str(exc.value)
