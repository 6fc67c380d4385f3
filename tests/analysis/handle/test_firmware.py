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


@pytest.mark.parametrize("variant", list(up.Variant))
def test_online_predictor_equals_firmware_tick_with_a_fresh_fit(variant):
    # predictor = online: at every update the coefficients are refitted to the last `window` positions, the
    # same law as analysis.control.upsampling.firmware_tick with coefficients=None (term by term)
    T, K, B, L, p, w = 1e-3, 2.5e3, 0.4, 4, 2, 12
    rng = np.random.default_rng(11)
    x = np.cumsum(rng.normal(size=60)) * 1e-4
    cfg = HandleFirmwareConfig(period_s=T, upsampling=L, variant=variant, ar_coefficients=(2.0, -1.0),
                               wall=WallLaw(kind=WallKind.BILATERAL, stiffness_N_per_m=K, damping_N_s_per_m=B),
                               predictor=up.Predictor.ONLINE, ar_order=p, ar_window=w)
    ctl = HandleFirmware(cfg)
    ctl.reset(x[0])
    fw = up.Firmware(period_s=T, upsampling=L, wall_damping_N_s_per_m=B, variant=variant, order=p, window=w)
    f = [K * x[0]] * 2
    hist = [x[0]] * w
    for xi in x[1:]:
        out = ctl.step(xi)
        hist.append(xi)
        ref = up.firmware_tick(fw, K, hist[-w:], f)
        np.testing.assert_allclose(out, ref.forces_N, rtol=1e-10, atol=1e-12)
        f = [f[1], K * xi + B * (xi - hist[-2]) / T]
    rep = ctl.predictor_report()
    # variant none holds f_i: the predictor is never run, and the report says so (0 updates)
    assert rep["predictor"] == "online"
    assert rep["ar_updates"] == (0 if variant is up.Variant.NONE else x.size - 1)


def test_online_predictor_reports_the_coefficients_of_a_damped_oscillation():
    # x_k = e^{−σkT} cos(ωkT) obeys x_{k+1} = 2e^{−σT}cos(ωT) x_k − e^{−2σT} x_{k−1} exactly (closed form of
    # the AR(2) recursion of a damped sinusoid): the fit reports those coefficients and a rounding-level residual
    T, sigma, omega = 1e-3, 3.0, 70.0
    k = np.arange(200)
    x = 1e-3 * np.exp(-sigma * k * T) * np.cos(omega * k * T)
    cfg = HandleFirmwareConfig(period_s=T, upsampling=2, variant=up.Variant.AS_INTENDED, ar_coefficients=(2.0, -1.0),
                               wall=WallLaw(kind=WallKind.BILATERAL, stiffness_N_per_m=1e3, damping_N_s_per_m=0.0),
                               predictor=up.Predictor.ONLINE, ar_order=2, ar_window=16)
    ctl = HandleFirmware(cfg)
    ctl.reset(x[0])
    for xi in x[1:]:
        ctl.step(xi)
    rep = ctl.predictor_report()
    a = (2.0 * np.exp(-sigma * T) * np.cos(omega * T), -np.exp(-2.0 * sigma * T))
    np.testing.assert_allclose(rep["ar_last_coefficients"], a, rtol=1e-6)
    assert rep["ar_last_status"] == "fitted"
    # the first 15 updates see a history padded with the power-up reading: fallback or a fit on it
    assert rep["ar_fitted_fraction"] > 0.9
    assert rep["ar_median_residual_rms_m"] < 1e-12


def test_online_predictor_at_rest_falls_back_and_says_so():
    # a constant (unexciting) history: every update falls back to (2, −1), finite forces, counted
    cfg = HandleFirmwareConfig(period_s=1e-3, upsampling=4, variant=up.Variant.AS_INTENDED, ar_coefficients=(2.0, -1.0),
                               wall=WallLaw(kind=WallKind.BILATERAL, stiffness_N_per_m=1e3, damping_N_s_per_m=0.1),
                               predictor=up.Predictor.ONLINE, ar_order=3, ar_window=8)
    ctl = HandleFirmware(cfg)
    ctl.reset(2e-3)
    for _ in range(20):
        out = ctl.step(2e-3)
        np.testing.assert_allclose(out, 2.0, rtol=1e-12)  # K x at rest
    rep = ctl.predictor_report()
    assert rep["ar_fitted_fraction"] == 0.0 and rep["ar_fallbacks"] == {"unexciting": 20}
    assert rep["ar_last_coefficients"] == (2.0, -1.0, 0.0)


def test_online_predictor_window_shorter_than_twice_the_order_is_refused():
    with pytest.raises(ValueError, match=r"window = 5: allowed integers ≥ 2·order = 6"):
        HandleFirmwareConfig(period_s=1e-3, upsampling=1, variant=up.Variant.NONE, ar_coefficients=(2.0, -1.0),
                             wall=WallLaw(kind=WallKind.BILATERAL, stiffness_N_per_m=1e3, damping_N_s_per_m=0.0),
                             predictor=up.Predictor.ONLINE, ar_order=3, ar_window=5)
