"""hapticopt.analysis.prrr.loop.firmware_ioic: the impedance controller + SEA loops of the IOIC mode is
the 3-PRRR firmware's spring law when the reference stands still."""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from hapticopt.analysis.control import ioic_online
from hapticopt.analysis.loop.scene import EnvKind, load_scene
from hapticopt.analysis.prrr.loop import closed_loop
from hapticopt.analysis.prrr.loop.firmware_ioic import PrrrIoicConfig, PrrrIoicController
from hapticopt.analysis.prrr.loop.firmware import ScalarController
from hapticopt.design.io import load_preset

DESIGN = load_preset("prrr-paper")


def test_render_with_a_still_reference_is_the_spring_law():
    """F = K_t(p_r − p) + B_t(0 − ṗ) (+ weight) through the SEA loop equals ScalarController rendering a
    spring K_t, damper B_t anchored at p_r (seed 002 firmware), tick by tick on random counts."""
    st = closed_loop.setup(DESIGN, load_scene("stiffness-25"))
    kt, bt = 7e3, 30.0
    p_r = np.array([1e-3, -2e-3, 0.5e-3])
    cfg = dataclasses.replace(st.cfg, env=EnvKind.SPRING, friction_compensation=False)
    gains = st.gains._replace(stiffness=jnp.full(3, kt), damping=jnp.full(3, bt), anchor=jnp.asarray(p_r))
    ref = ScalarController(cfg, gains)
    sc = load_scene("prrr-ioic")
    ioic_cfg = PrrrIoicConfig(base=cfg, gains=gains, outer=ioic_online.outer_config(sc, cfg.period), axis=0,
                              x_start=(0.0, 0.0, 0.0), motion=sc.motion, mass=DESIGN.end_effector.mass,
                              tracking_stiffness=kt, tracking_damping=bt)
    ctl = PrrrIoicController(ioic_cfg)
    rng = np.random.default_rng(5)
    s0 = rng.integers(-50, 50, 3).astype(float)
    ref.reset(s0)
    ctl.reset(s0)
    for _ in range(50):
        s = s0 + rng.integers(-200, 200, 3)
        d = rng.integers(-300, 300, 3).astype(float)
        want = ref.step(s, d)
        got = ctl.render(p_r, np.zeros(3), np.zeros(3), s, d, np.zeros(3))
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(ctl.last_force, ref.last_force, rtol=1e-12, atol=1e-12)


def test_feed_forward_and_force_cancellation_enter_the_command():
    """The mass feed-forward M ẍ_r and −F_h (seed 001 eq 17's −τ_ext, Cartesian) add to F."""
    st = closed_loop.setup(DESIGN, load_scene("stiffness-25"))
    sc = load_scene("prrr-ioic")
    cfg = PrrrIoicConfig(base=dataclasses.replace(st.cfg, gravity_compensation=False), gains=st.gains,
                         outer=ioic_online.outer_config(sc, st.cfg.period), axis=0, x_start=(0.0, 0.0, 0.0),
                         motion=sc.motion, mass=DESIGN.end_effector.mass, tracking_stiffness=1e4, tracking_damping=0.0)
    ctl = PrrrIoicController(cfg)
    ctl.reset(np.zeros(3))
    ctl.render(np.zeros(3), np.zeros(3), np.array([2.0, 0.0, 0.0]), np.zeros(3), np.zeros(3), np.array([0.0, 0.5, 0.0]))
    np.testing.assert_allclose(ctl.last_force, [2.0 * DESIGN.end_effector.mass, -0.5, 0.0], rtol=1e-15)
