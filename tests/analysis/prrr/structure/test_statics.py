"""3-PRRR statics against seed 002's closed forms and tables."""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from hapticopt.analysis.prrr.structure import statics as prrr_statics
from hapticopt.design.prrr.kinematics import params_of
from hapticopt.analysis.status import Status
from hapticopt.design import io


def test_prrr_paper_max_force_is_table_1(prrr_paper):
    # seed 002 Table 1: 1378 (digest: 1378; Table prints 1379), 1194, 3581 N; ±0.2 %
    r = prrr_statics.evaluate(prrr_paper)
    np.testing.assert_allclose(r.max_force, [1378, 1194, 3581], rtol=2e-3)
    assert r.status is Status.OK


def test_prrr_paper_stiffness_limit_is_eq_15(prrr_paper):
    # seed 002 eq 15 (corrected, digest): k/2, k/2, 3k with k = 56.27 N/mm → 28.14, 28.14, 168.8 N/mm
    m = prrr_statics.evaluate(prrr_paper).metrics()
    np.testing.assert_allclose(m["stiffness_limit_N_per_mm"], [28.14, 28.14, 168.8], rtol=2e-3)


def test_prrr_paper_effective_mass_is_eq_7(prrr_paper):
    # seed 002 eq 7 at β = π/3: (M/9)[[13, −5, −5], [−5, 13, −5], [−5, −5, 13]], M = 0.66 kg
    M = 0.66
    expected = M / 9 * np.array([[13, -5, -5], [-5, 13, -5], [-5, -5, 13]])
    np.testing.assert_allclose(prrr_statics.evaluate(prrr_paper).effective_mass, expected, rtol=1e-13)


def test_prrr_paper_condition_is_sqrt6(prrr_paper):
    # digest table: cond₂(J) = 2.449 = √6 at β = π/3
    assert prrr_statics.evaluate(prrr_paper).condition == pytest.approx(math.sqrt(6), rel=1e-13)


def test_isotropic_beta_table_5(prrr_paper):
    # seed 002 Table 5 / digest: β = 35.26° (0.196π) gives cond(J) = 1 and equal stiffness limits
    r = prrr_statics.evaluate(io.apply_overrides(prrr_paper, ["geometry.beta_deg=35.26"]))
    assert r.condition == pytest.approx(1.0, abs=1e-3)
    k = r.stiffness_limit
    assert k[0] == pytest.approx(k[1], rel=1e-12)
    assert k[0] == pytest.approx(k[2], rel=1e-3)
    np.testing.assert_allclose(r.max_force, [3374, 2922, 3581], rtol=2e-3)  # digest table, β = 0.196π


def test_exact_isotropic_angle_gives_cond_one():
    beta = math.atan(1 / math.sqrt(2))  # digest: isotropic angle
    J = prrr_statics.jacobian(jnp.asarray(beta))
    assert float(prrr_statics.condition_2norm(J)) == pytest.approx(1.0, abs=1e-12)
    assert float(prrr_statics.condition_frobenius(J)) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("beta_deg", [5.0, 20.0, 45.0, 70.0, 85.0])
def test_closed_forms_at_any_beta(prrr_paper, beta_deg):
    # digest: F_x = 2F/T, F_y = √3F/T, F_z = 3F; pure x = 3F/(2T); k_x = k_y = 3k/(2T²), k_z = 3k
    d = io.apply_overrides(prrr_paper, [f"geometry.beta_deg={beta_deg}"])
    r = prrr_statics.evaluate(d)
    T, F, k = math.tan(math.radians(beta_deg)), d.actuator.force_limit, d.actuator.spring
    np.testing.assert_allclose(r.max_force, [2 * F / T, math.sqrt(3) * F / T, 3 * F], rtol=1e-12)
    assert r.max_pure_force[0] == pytest.approx(3 * F / (2 * T), rel=1e-12)
    np.testing.assert_allclose(r.stiffness_limit, [3 * k / (2 * T**2), 3 * k / (2 * T**2), 3 * k], rtol=1e-12)
    # eq 7 general entry: (M/9)(1 + 4T²) on the diagonal
    assert r.effective_mass[0, 0] == pytest.approx(d.end_effector.mass / 9 * (1 + 4 * T**2), rel=1e-12)


@pytest.mark.parametrize("beta_deg", [1.0, 89.0])
def test_extreme_beta_is_finite_or_not_assemblable(prrr_paper, beta_deg):
    r = prrr_statics.evaluate(io.apply_overrides(prrr_paper, [f"geometry.beta_deg={beta_deg}"]))
    if beta_deg == 1.0:
        # the reach ellipse's u semi-axis is (d3 + d4) sin 1° = 2.8 mm about c_u / sin 1° = −1.72 m
        # (c_u = d1 − (b5 + r4) cos β = −30 mm, workspace.py): no pose closes the chain (issue 21)
        assert r.status is Status.NOT_ASSEMBLABLE and "does not close" in r.message
        assert np.all(np.isnan(r.metrics()["max_force_N"]))
        assert np.all(np.isfinite(r.max_force))  # the closed forms themselves stay finite
        return
    assert r.status is Status.OK
    for v in r.metrics().values():
        assert np.all(np.isfinite(np.asarray(v, dtype=float)))


def test_frobenius_condition_gradient_matches_finite_difference():
    """The smooth condition form has a well-defined gradient through the isotropic angle."""
    f = lambda b: prrr_statics.condition_frobenius(prrr_statics.jacobian(b))  # noqa: E731
    for beta in (0.4, math.atan(1 / math.sqrt(2)), 1.2):
        g = float(jax.grad(f)(jnp.asarray(beta)))
        h = 1e-6
        fd = (float(f(jnp.asarray(beta + h))) - float(f(jnp.asarray(beta - h)))) / (2 * h)
        assert g == pytest.approx(fd, rel=1e-6, abs=1e-8)


def test_batched_statics_equal_single(prrr_paper):
    designs = [io.apply_overrides(prrr_paper, [f"geometry.beta_deg={b}"]) for b in (20, 35, 50, 65)]
    from hapticopt.design.prrr.kinematics import stack_params

    P = stack_params(designs)
    n = len(designs)
    out = jax.vmap(prrr_statics.statics_arrays)(P, jnp.full(n, 56270.0), jnp.full(n, 1000.0), jnp.full(n, 0.66))
    for i, d in enumerate(designs):
        one = prrr_statics.statics_arrays(params_of(d), jnp.asarray(56270.0), jnp.asarray(1000.0), jnp.asarray(0.66))
        for key in one:
            np.testing.assert_allclose(out[key][i], one[key], rtol=1e-12, atol=1e-12)


def test_numpy_single_path_equals_jax_path(prrr_paper):
    """evaluate() uses numpy (no jit at CLI start-up); the jax path serves batches — same numbers."""
    r = prrr_statics.evaluate(prrr_paper)
    a = prrr_paper.actuator
    out = jax.jit(prrr_statics.statics_arrays)(params_of(prrr_paper), jnp.asarray(a.spring),
                                               jnp.asarray(a.force_limit), jnp.asarray(prrr_paper.end_effector.mass))
    np.testing.assert_allclose(r.max_force, out["max_force"], rtol=1e-14)
    np.testing.assert_allclose(r.effective_mass, out["effective_mass"], rtol=1e-14, atol=1e-15)
    assert r.condition == pytest.approx(float(out["condition"]), rel=1e-14)


@pytest.mark.hardcase
@pytest.mark.parametrize("beta_deg, status", [
    (60.0, "ok"),  # cond √6 (seed digest)
    (89.9999999, "ill-conditioned"),  # cond ≈ 8e8: rcond 1.2e-9, ~3 decades from both bands
    (1e-7, "ill-conditioned"),  # cond ≈ 4e8
    (90.0 - 1e-13, "singular"),  # cond ≈ 8e14: rcond 1.2e-15, 3 decades below RCOND_SINGULAR
])
def test_statics_status_from_the_reciprocal_condition_number(beta_deg, status):
    """Issue 14: statics said ok at β = 89.999999999° (cond 8.1e10) and β = 1e-6°; now a banded verdict
    with NaN metrics whenever the status is not ok."""
    import dataclasses
    import math

    from hapticopt.analysis.prrr.structure import statics
    from hapticopt.design import io

    d = io.load_preset("prrr-paper")
    d = dataclasses.replace(d, geometry=dataclasses.replace(d.geometry, beta=math.radians(beta_deg)))
    r = statics.evaluate(d)
    assert str(r.status) == status
    m = r.metrics()
    assert all(math.isnan(v) for v in m["max_force_N"]) == (status != "ok")
    assert math.isnan(m["jacobian_condition"]) == (status != "ok")


def test_from_arrays_many_equals_from_arrays():
    # the batched draft evaluator's result step against the per-design one (the reference), on stacked
    # numpy statics of designs across the verdicts: ok, ill-conditioned and singular J (β near 90° and 0°),
    # and a chain that does not close (d2 = 300 mm: seed digest's example, not-assemblable)
    base = io.load_preset("prrr-paper")
    geo = lambda **kw: dataclasses.replace(base, geometry=dataclasses.replace(base.geometry, **kw))  # noqa: E731
    designs = [base, geo(beta=math.radians(89.999999)), geo(beta=math.radians(1e-12)), geo(d2=0.300),
               geo(beta=math.radians(50.0))]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        rows = [prrr_statics.statics_arrays(prrr_statics.params_np(d), d.actuator.spring, d.actuator.force_limit,
                                       d.end_effector.mass, xp=np) for d in designs]
    stacked = {k: np.stack([np.asarray(r[k]) for r in rows]) for k in rows[0]}
    many = prrr_statics.from_arrays_many(designs, stacked)
    statuses = set()
    for d, r, got in zip(designs, rows, many):
        ref = prrr_statics.from_arrays(d, r)
        assert (got.status, got.message) == (ref.status, ref.message)
        for f in ("jacobian", "condition", "condition_frobenius", "effective_mass", "stiffness_matrix",
                  "stiffness_limit", "max_force", "max_pure_force"):
            assert np.array_equal(getattr(got, f), getattr(ref, f), equal_nan=True), f
        statuses.add(ref.status)
    assert len(statuses) >= 3
