"""The 3-PRRR as manufactured (design/prrr/tolerance.py): exact reduction to the nominal kinematics,
closure of FK ∘ IK off nominal, J against finite differences of FK, linear growth of the constancy
deviation with one axis tilt."""

from __future__ import annotations

import numpy as np
import pytest

from hapticopt.design import io
from hapticopt.design.prrr import kinematics as kin
from hapticopt.design.prrr import tolerance as tol


def residual_norm(dev: tol.Device, st: tol.State) -> np.ndarray:
    """Largest |closure residual| of each state [m, or rad for the compliance rows] (…,)."""
    d = tol._pose_dev(dev, st)
    f, h = tol._residual(d, st, tol._chain(d, st.sliders, st.theta))
    return np.maximum(np.max(np.abs(f), axis=(-2, -1)), np.max(np.abs(h), axis=-1))


@pytest.fixture(scope="module")
def design():
    return io.load_preset("prrr-paper")


@pytest.fixture(scope="module")
def poses():
    return tol.pose_grid()


def _random_errors(n: int, seed: int = 3) -> np.ndarray:
    """Errors of ISO 2768-m's order (lengths 0.1 mm, angles 1 mrad) in every component of every leg."""
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 3, tol.N_ERRORS)) * np.where(tol.ANGULAR, 1e-3, 1e-4)


def test_pose_grid_has_at_least_100_poses_and_the_home_pose(poses):
    assert len(poses) >= 100
    assert np.linalg.norm(poses[tol.home_index(poses)]) == 0.0


def test_zero_errors_reduce_to_the_nominal_jacobian(design, poses):
    """Source: seed 002 eq (2), kin.jacobian: J is the same at every pose; here to 1e-12 over the grid."""
    dev = tol.build(design, tol.zero_errors(1))
    st = tol.inverse_kinematics(design, dev, poses)
    j = tol.jacobian(dev, st)
    j_nom = np.asarray(kin.jacobian(design.geometry.beta, xp=np))
    assert np.max(np.abs(j - j_nom)) <= 1e-12
    # and the nominal IK's sliders and angles (kinematics.inverse_kinematics, the CAD's branch)
    ik = kin.inverse_kinematics(kin.params_np(design), poses, xp=np)
    assert np.max(np.abs(st.sliders[0] - ik.sliders)) <= 1e-12
    assert np.max(np.abs(st.theta[0] - np.asarray(ik.theta)[:, tol.BRANCH, :, :2])) <= 1e-12
    assert np.max(np.abs(st.phi)) <= 1e-12


def test_forward_of_inverse_closes_off_nominal(design, poses):
    errors = _random_errors(3)
    for k in range(3):
        dev = tol.build(design, errors[k])
        st = tol.inverse_kinematics(design, dev, poses)
        assert np.max(residual_norm(dev, st)) <= 1e-12
        fk = tol.forward_kinematics(design, dev, st.sliders)
        assert np.max(np.abs(fk.p - poses)) <= 1e-9
        assert np.max(np.abs(fk.phi - st.phi)) <= 1e-9


def test_jacobian_equals_finite_differences_of_forward_kinematics(design, poses):
    """J from the implicit function theorem against a central difference of FK (h = 1 µm: truncation
    ~h²·|p'''| ~ 1e-12, round-off ~1e-16/h ~ 1e-10)."""
    dev = tol.build(design, _random_errors(1)[0])
    k = 20
    st = tol.inverse_kinematics(design, dev, poses[k])
    j = tol.jacobian(dev, st)
    h = 1e-6
    fd = np.zeros((3, 3))
    for col in range(3):
        step = np.eye(3)[col] * h
        fd[:, col] = (tol.forward_kinematics(design, dev, st.sliders + step).p
                      - tol.forward_kinematics(design, dev, st.sliders - step).p) / (2 * h)
    assert np.max(np.abs(j - fd)) <= 1e-8
    j_nom = np.asarray(kin.jacobian(design.geometry.beta, xp=np))
    assert np.max(np.abs(j - j_nom)) > 1e-4  # the errors do change J (the check above is not vacuous)


@pytest.mark.parametrize("axis", ["r1_tilt_t", "r2_tilt_v", "r3_tilt_t"])
def test_constancy_deviation_grows_linearly_with_one_axis_tilt(design, poses, axis):
    """Zero errors: J constant (deviation 0). One tilt δ: J(p) − J_nom = δ S(p) + O(δ²), so
    max_p ‖·‖/δ tends to a constant: three δ a decade apart agree within a few per cent."""
    deltas = np.array([1e-5, 1e-4, 1e-3])
    errors = np.zeros((3, 3, tol.N_ERRORS))
    errors[:, 0, tol.error_index(axis)] = deltas
    r = tol.offnominal(design, errors, poses)
    ratios = r.constancy / deltas
    assert np.all(ratios > 0.01)  # the tilt does make J pose-dependent
    assert np.max(ratios) / np.min(ratios) - 1.0 <= 0.03, ratios
    zero = tol.offnominal(design, tol.zero_errors(1), poses)
    assert zero.constancy[0] <= 1e-12 and zero.rotation[0] <= 1e-12 and abs(zero.margin_loss[0]) <= 1e-12


def test_offnominal_is_batched_and_the_same_per_device(design, poses):
    errors = _random_errors(5)
    whole = tol.offnominal(design, errors, poses, chunk=2)
    one = tol.offnominal(design, errors[3:4], poses)
    for a, b in zip(whole, one):
        assert a[3] == pytest.approx(b[0], rel=1e-12, abs=1e-15)


def test_a_tilted_rail_rotates_the_platform(design, poses):
    """A rail tilt alone keeps every R axis parallel to its bore: no misfit and no platform rotation to
    first order (the legs' n_i still equal wp_i); a tilted R3 bore in the platform alone turns it."""
    e = np.zeros((2, 3, tol.N_ERRORS))
    e[0, 0, tol.error_index("rail_tilt_u")] = 1e-3
    e[1, 0, tol.error_index("rp_tilt_v")] = 1e-3
    r = tol.offnominal(design, e, poses)
    assert r.misfit[0] <= 1e-12 and r.rotation[0] <= 1e-12
    assert r.rotation[1] > 1e-4 and r.misfit[1] > 1e-4
