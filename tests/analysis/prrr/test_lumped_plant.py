"""hapticopt.analysis.prrr.lumped_plant: exact linear part, statics, Coulomb stick-slip, the Plant protocol."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hapticopt.analysis.prrr.lumped_plant import (
    LumpedPlant,
    PlantMode,
    build_model,
    discretise,
    solve_friction,
)
from hapticopt.analysis.loop.plant import Plant
from hapticopt.analysis.loop.scene import Effect, load_scene, resolve


def _model(prrr_paper, scene):
    return build_model(prrr_paper, scene, resolve(scene))


def test_zoh_is_exact_composition(prrr_paper):
    """exp(A·10h) = exp(A·h)^10: one big step equals ten small ones for the linear part."""
    m = _model(prrr_paper, load_scene("stiffness-25"))
    big, small = discretise(m, 1e-3), discretise(m, 1e-4)
    assert np.linalg.matrix_power(small.Ad, 10) == pytest.approx(big.Ad, abs=1e-10)


def test_equivalent_mass_eq7_and_static_spring(prrr_paper):
    sc = dataclasses.replace(load_scene("free-space"), effects=frozenset({Effect.SEA_COMPLIANCE, Effect.MOTOR_DYNAMICS}))
    m = _model(prrr_paper, sc)
    assert m.mode == PlantMode.FULL
    Me = m.Q[9:12, 9:12]
    # seed 002 eq 7 at β = π/3: (M/9)[[13, −5, −5], …], M = 0.66 kg
    assert Me == pytest.approx(0.66 / 9 * np.array([[13, -5, -5], [-5, 13, -5], [-5, -5, 13]]))
    # constant motor force F on every leg: static spring force ηF, with output free it accelerates both
    plant = LumpedPlant(m, 1e-3, 1)
    plant.advance(np.ones((1, 3)))
    assert np.all(np.isfinite(plant.observe().position))
    assert isinstance(plant, Plant)


def test_coulomb_stick_and_slip_1d():
    """Scalar G: λ is exact in one sweep — stuck below F_c, sliding at −F_c·sign(v) above."""
    G = np.diag([0.01, 0.01, 0.01])
    lam = solve_friction(np, np.array([0.02, -0.005, 0.0]), G, 1.0, np.zeros(3), 1)
    assert lam == pytest.approx([-1.0, 0.5, 0.0])  # slides (v stays > 0), sticks (v → 0), at rest


def test_friction_holds_output_below_breakaway(prrr_paper):
    """A small constant actuator force on a resting output below friction: the output must not move."""
    sc = dataclasses.replace(load_scene("free-space"), effects=frozenset(
        {Effect.SEA_COMPLIANCE, Effect.MOTOR_DYNAMICS, Effect.VISCOUS_FRICTION, Effect.COULOMB_FRICTION}))
    m = _model(prrr_paper, sc)
    plant = LumpedPlant(m, 1e-3, 5)
    for _ in range(300):
        plant.advance(np.full((1, 3), 1.0))  # ηF ≈ 0.92 N per leg < F_c = 3 N
    # velocity-level time stepping: v = 0 exactly at every substep end; the position within a substep
    # is first-order, so a stuck slider creeps by < 1 % of an encoder count (1.25 µm) in 0.3 s
    assert np.abs(plant.x[m.out_pos]).max() < 1e-8 * 1.25 * 3
    assert np.abs(plant.x[m.out_vel]).max() < 1e-9  # zero up to the Gauss–Seidel residual (12 sweeps)
    for _ in range(300):
        plant.advance(np.full((1, 3), 10.0))  # ≈ 9.2 N per leg > 3 N: slides
    assert np.abs(plant.x[m.out_pos]).max() > 1e-6
