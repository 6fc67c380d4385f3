"""hapticopt.analysis.prrr.loop.lumped_plant: exact linear part, statics, Coulomb stick-slip, the Plant protocol."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from prrr_stepped_loop import LumpedPlant

from hapticopt.analysis.prrr.loop.lumped_plant import (
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


def _at_home():
    """The free-space scene as a base for plant tests, started at home (the scene starts where its hand
    circle starts, y = 4 mm)."""
    return dataclasses.replace(load_scene("free-space"), initial_offset=(0.0, 0.0, 0.0))


def test_equivalent_mass_eq7_and_static_spring(prrr_paper):
    sc = dataclasses.replace(_at_home(), effects=frozenset({Effect.SEA_COMPLIANCE, Effect.MOTOR_DYNAMICS}))
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
    sc = dataclasses.replace(_at_home(), effects=frozenset(
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


# ---------------------------------------------------------------------- R-joint friction (issue 19)
def test_r_joint_rates_match_finite_differences_and_have_no_z_column(prrr_paper):
    """∂θ/∂p by autodiff vs central differences of the IK; z turns no R joint (seed digest: ρ is
    independent of z); within ±4 mm of home (the scenes' stroke) ∂θ/∂p changes by < 7 %."""
    from hapticopt.design.prrr.cad import DEFAULT_BRANCH
    from hapticopt.design.prrr.kinematics import inverse_kinematics, params_of
    from hapticopt.analysis.prrr.loop.lumped_plant import r_joint_rates

    H = r_joint_rates(prrr_paper)
    P = params_of(prrr_paper)
    h = 1e-6
    fd = np.stack([(np.asarray(inverse_kinematics(P, h * e, xp=np).theta[DEFAULT_BRANCH])
                    - np.asarray(inverse_kinematics(P, -h * e, xp=np).theta[DEFAULT_BRANCH])).reshape(9) / (2 * h)
                   for e in np.eye(3)], axis=-1)
    assert H == pytest.approx(fd, abs=1e-6 * np.abs(H).max())
    assert np.abs(H[:, 2]).max() < 1e-9 * np.abs(H).max()
    from hapticopt.design.prrr.kinematics import joint_rate_jacobian

    for p in ([4e-3, 0, 0], [0, 4e-3, 0], [-4e-3, 0, 0]):
        H4 = np.asarray(joint_rate_jacobian(P, np.array(p), DEFAULT_BRANCH)).reshape(9, 3)
        assert np.abs(H4 - H).max() < 0.07 * np.abs(H).max()


def _ideal_plant(prrr_paper, location):
    """Ideal force sources (no motor dynamics) with Coulomb friction at ``location``: the command is the
    slider force u, the Cartesian force on the output is J⁻ᵀu."""
    from hapticopt.analysis.loop.scene import FrictionLocation

    sc = dataclasses.replace(_at_home(), effects=frozenset({Effect.COULOMB_FRICTION}),
                             friction_location=FrictionLocation(location))
    m = _model(prrr_paper, sc)
    assert m.mode == PlantMode.IDEAL
    return m, LumpedPlant(m, 1e-3, 5)


@pytest.mark.parametrize("axis", [0, 1])
def test_r_joint_friction_breakaway_is_the_virtual_work_sum(prrr_paper, axis):
    """Holding force along x (y) = τ_c Σ_j |∂θ_j/∂p_a| (virtual work over the nine joints): 0.95 × it
    leaves the output at rest, 1.05 × it slides. At the default τ_c the x value is 3 N (params doc)."""
    from hapticopt.analysis.prrr.loop.lumped_plant import r_joint_rates

    H = r_joint_rates(prrr_paper)
    F_b = prrr_paper.structure.joint_friction * np.abs(H[:, axis]).sum()
    if axis == 0:
        assert F_b == pytest.approx(3.0, rel=2e-3)  # 0.0384 N·m × 78.06 rad/m
    else:
        assert F_b == pytest.approx(3.0 * 2 / np.sqrt(3), rel=2e-3)  # y: 90.14 rad/m = 2/√3 × the x sum
    m, plant = _ideal_plant(prrr_paper, "r_joints")
    for factor, moves in ((0.95, False), (1.05, True)):
        plant.reset()
        F = np.zeros(3)
        F[axis] = factor * F_b
        for _ in range(200):
            plant.advance((m.J.T @ F)[None])
        p = plant.observe().position
        assert (abs(p[axis]) > 1e-6) == moves, (factor, p)


def test_r_joint_friction_does_not_hold_z_but_slider_friction_does(prrr_paper):
    """The paper compensates x and y only: R-joint friction has no z component; slider friction does."""
    F = np.array([0.0, 0.0, 2.0])  # 2 N up, weight off
    for location, moves in (("r_joints", True), ("sliders", False)):
        m, plant = _ideal_plant(prrr_paper, location)
        for _ in range(200):
            plant.advance((m.J.T @ F)[None])
        assert (plant.observe().position[2] > 1e-6) == moves, location
