"""analysis/handle/firmware.py: the scene firmware is the shared upsampling law (bilateral wall) and the
one-sided contact never pulls."""

from __future__ import annotations

import numpy as np
import pytest

from hapticopt.analysis.control import upsampling as up
from hapticopt.analysis.handle.firmware import HandleFirmware, HandleFirmwareConfig, WallKind, WallLaw


@pytest.mark.parametrize("variant", list(up.Variant))
@pytest.mark.parametrize("L", [1, 3])
def test_bilateral_law_equals_firmware_tick(variant, L):
    # the same law as analysis.control.upsampling.firmware_tick (fixed (2, −1)) on a random history
    T, K, B = 1e-3, 2.5e3, 0.4
    rng = np.random.default_rng(7)
    x = np.cumsum(rng.normal(size=40)) * 1e-4
    cfg = HandleFirmwareConfig(period_s=T, upsampling=L, variant=variant, ar_coefficients=(2.0, -1.0),
                               wall=WallLaw(kind=WallKind.BILATERAL, stiffness_N_per_m=K, damping_N_s_per_m=B))
    ctl = HandleFirmware(cfg)
    ctl.reset(x[0])
    fw = up.Firmware(period_s=T, upsampling=L, wall_damping_N_s_per_m=B, variant=variant, coefficients=(2.0, -1.0))
    f = [K * x[0]] * 2
    hist = [x[0], x[0]]
    for xi in x[1:]:
        out = ctl.step(xi)
        hist.append(xi)
        ref = up.firmware_tick(fw, K, hist, f)
        np.testing.assert_allclose(out, ref.forces_N, rtol=1e-12, atol=1e-15)
        f = [f[1], K * xi + B * (xi - hist[-2]) / T]


def test_one_sided_contact_never_pulls():
    law = WallLaw(kind=WallKind.ONE_SIDED, stiffness_N_per_m=3e3, damping_N_s_per_m=5.0, anchor_m=0.0, half_width_m=5e-3)
    assert law.force(4e-3, -1.0) == 0.0  # outside: no force whatever the velocity
    assert law.force(6e-3, 0.0) == pytest.approx(3.0)  # 1 mm in: K·depth, pushing towards −x (f_m > 0)
    assert law.force(6e-3, -10.0) == 0.0  # leaving fast: the damper would pull; clipped
    assert law.force(-6e-3, 0.0) == pytest.approx(-3.0)  # the other wall pushes towards +x
