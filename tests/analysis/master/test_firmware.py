"""Tests of hapticopt.analysis.master.firmware: the transparency mode's model-based compensation."""

from __future__ import annotations

import dataclasses

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import numpy as np

from hapticopt.analysis.master import dynamics as md
from hapticopt.analysis.master.firmware import compensation_torque
from hapticopt.design.io import load_preset


def test_compensation_torque_is_the_links_inverse_dynamics_without_gravity():
    """M̂ q̈ + Ĉ q̇ of the links (weights 1 − counterweight) equals the jax reference M q̈ + C(q, q̇) q̇ of
    the same design with the counterweights removed (gravity not included)."""
    d = load_preset("master-paper")
    model = md.model_of(d)
    weights = 1.0 - np.asarray(model.counterweight)
    no_cw = dataclasses.replace(d, counterweights=dataclasses.replace(d.counterweights, upper_mass=0.0,
                                                                      forearm_mass=0.0))
    ref = md.model_of(no_cw)
    rng = np.random.default_rng(3)
    for _ in range(4):
        q = np.array([rng.uniform(-0.5, 0.5), rng.uniform(0.2, 1.2), rng.uniform(-1.0, 0.3)])
        qd, qdd = rng.normal(size=3), rng.normal(size=3)
        expected = np.asarray(md.mass_matrix(ref, q)) @ qdd + np.asarray(md.coriolis(ref, q[None], qd[None]))[0]
        got = compensation_torque(model, weights, q, qd, qdd)
        np.testing.assert_allclose(got, expected, rtol=1e-6, atol=1e-9)  # central differences of M (h = 1e-6)
