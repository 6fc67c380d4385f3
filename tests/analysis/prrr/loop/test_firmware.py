"""hapticopt.analysis.prrr.loop.firmware: the control law term by term (closed forms), batching, the object API."""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

from hapticopt.analysis.prrr.loop import firmware as fw
from hapticopt.analysis.loop.scene import BoxMode, EnvKind, load_scene, resolve


def _law(prrr_paper, scene_name="stiffness-25", **cfg_changes):
    sc = load_scene(scene_name)
    cfg, gains = fw.build(prrr_paper, sc, resolve(sc))
    return dataclasses.replace(cfg, **cfg_changes), gains


def _counts(gains, p):
    """Slider counts of end-effector position p (inverse of eq 1: D = J⁻¹ p)."""
    return np.linalg.solve(np.asarray(gains.J), p) / float(gains.resolution)


def test_spring_force_and_force_loop(prrr_paper):
    cfg, g = _law(prrr_paper, gravity_compensation=False, velocity_alpha=0.0)
    p = np.array([1e-3, 0.0, 0.0])
    s0 = fw.init_state(cfg, g, jnp.asarray(_counts(g, p)))
    _, cmd, F = fw.step(cfg, g, s0, jnp.asarray(_counts(g, p)), jnp.zeros(3))
    assert np.asarray(F) == pytest.approx([-25.0, 0, 0], abs=1e-9)  # −K_v δ, 25 N/mm × 1 mm, ṗ̂ = 0
    f_r = np.asarray(g.J).T @ np.asarray(F)  # Jᵀ F_r
    assert np.asarray(cmd)[0] == pytest.approx(45.0 * f_r)  # K_p (f_r − k x̂) with x̂ = 0


def test_box_inside_and_outside(prrr_paper):
    cfg, g = _law(prrr_paper, "virtual-box", gravity_compensation=False, velocity_alpha=0.0)
    inside = np.array([5e-3, 0, 0])
    beyond = np.array([12e-3, -3e-3, 0])
    for p, expect in ((inside, [0, 0, 0]), (beyond, [-25e3 * 2e-3, 0, 0])):
        c = jnp.asarray(_counts(g, p))
        _, _, F = fw.step(cfg, g, fw.init_state(cfg, g, c), c, jnp.zeros(3))
        assert np.asarray(F) == pytest.approx(expect, abs=1e-9)  # eq 13, keep-inside
    cfg_o = dataclasses.replace(cfg, box_mode=BoxMode.OUTSIDE)
    p = np.array([8e-3, 2e-3, 0])  # inside the obstacle, shallowest along x (2 mm to the wall)
    c = jnp.asarray(_counts(g, p))
    _, _, F = fw.step(cfg_o, g, fw.init_state(cfg_o, g, c), c, jnp.zeros(3))
    assert np.asarray(F) == pytest.approx([25e3 * 2e-3, 0, 0], abs=1e-9)


def test_bspline_partition_of_unity_and_constant_reproduction(prrr_paper):
    from hapticopt.analysis.control.upsampling import Variant

    cfg, g = _law(prrr_paper, interpolation=5)
    W = fw.interpolation_weights(cfg)  # on [f_{i−2}, f_{i−1}, f_i, f̂_{i+1}, f̂_{i+2}]
    assert W.sum(axis=1) == pytest.approx(np.ones(5))  # eq 23 basis sums to one
    # default: as intended, u = 0 at (f_{i−1} + 4f_i + f̂_{i+1})/6 (= f_i for linear data)
    assert cfg.interpolation_variant is Variant.AS_INTENDED
    assert W[0] == pytest.approx([0, 1 / 6, 4 / 6, 1 / 6, 0])
    Wp = fw.interpolation_weights(dataclasses.replace(cfg, interpolation_variant=Variant.AS_PRINTED))
    assert Wp[0] == pytest.approx([1 / 6, 4 / 6, 1 / 6, 0, 0])  # as printed: (f_{i−2} + 4f_{i−1} + f_i)/6
    # the (2, −1) recursion continues a linear history: f̂_{i+1} = 4, f̂_{i+2} = 5 after 1, 2, 3
    h = np.array([[1.0] * 3, [2.0] * 3, [3.0] * 3])
    p1, p2 = fw.predictions((2.0, -1.0), h)
    assert p1 == pytest.approx([4.0] * 3) and p2 == pytest.approx([5.0] * 3)


def test_saturation_clips_motor_force(prrr_paper):
    cfg, g = _law(prrr_paper, gravity_compensation=False)
    c = jnp.asarray(_counts(g, np.array([0.0, 0, 0])))
    _, cmd, _ = fw.step(cfg, g, fw.init_state(cfg, g, c), c, jnp.full(3, 1e7))
    assert np.abs(np.asarray(cmd)).max() == pytest.approx(prrr_paper.actuator.force_limit / prrr_paper.actuator.efficiency)


def test_batched_gains_match_single(prrr_paper):
    cfg, g = _law(prrr_paper)
    K = np.array([[1e3, 0, 0], [5e3, 0, 0], [25e3, 0, 0]])
    gb = g._replace(stiffness=jnp.asarray(K))
    c = jnp.tile(jnp.asarray(_counts(g, np.array([1e-3, 0, 0]))), (3, 1))
    _, cmd_b, F_b = fw.step(cfg, gb, fw.init_state(cfg, gb, c), c, jnp.zeros((3, 3)))
    for i in range(3):
        gi = g._replace(stiffness=jnp.asarray(K[i]))
        _, cmd_i, F_i = fw.step(cfg, gi, fw.init_state(cfg, gi, c[i]), c[i], jnp.zeros(3))
        assert np.asarray(F_b[i]) == pytest.approx(np.asarray(F_i))


def test_controller_object_api(prrr_paper):
    cfg, g = _law(prrr_paper)
    ctl = fw.FirmwareController(cfg, g)
    assert ctl.period == 1e-3
    cmd = ctl.step(np.zeros(3), np.zeros(3))
    assert cmd.shape == (1, 3) and np.all(np.isfinite(cmd))
    assert cfg.env == EnvKind.SPRING
