"""Verdicts from an explicit reciprocal condition number (issue 14): fixed bands, fixed order.

Inputs sit at least two decades from a band (RCOND_SINGULAR = 1e-12, RCOND_ILL = 1e-6), so a
BLAS kernel's rounding (O(1e-16) relative) cannot move a verdict; ``.ci/run`` runs these under
two OpenBLAS kernels.
"""

from __future__ import annotations

import numpy as np
import pytest

from hapticopt.analysis import conditioning as c
from hapticopt.analysis.status import Status

pytestmark = pytest.mark.hardcase


def _diag_rotated(singular_values):
    """A full matrix with the given singular values (random orthogonal factors, seeded)."""
    rng = np.random.default_rng(14)
    q1, _ = np.linalg.qr(rng.normal(size=(len(singular_values),) * 2))
    q2, _ = np.linalg.qr(rng.normal(size=(len(singular_values),) * 2))
    return q1 @ np.diag(singular_values) @ q2


@pytest.mark.parametrize("smallest, status", [
    (1.0, Status.OK), (1e-4, Status.OK),  # 2 decades above RCOND_ILL
    (1e-8, Status.ILL_CONDITIONED), (1e-10, Status.ILL_CONDITIONED),  # 2 decades inside each side
    (1e-14, Status.SINGULAR), (0.0, Status.SINGULAR),
])
def test_bands(smallest, status):
    A = _diag_rotated([1.0, 0.5, smallest]) if smallest <= 0.5 else _diag_rotated([1.0, 1.0, smallest])
    v = c.classify(A, what="A")
    assert v.status is status
    assert v.rcond == pytest.approx(smallest, rel=1e-3, abs=1e-15)  # rcond = σ_min/σ_max by construction


def test_symmetric_scaling_ignores_units_and_order_is_singular_ill_then_definiteness():
    # stiff and soft DOFs six decades apart but decoupled: perfectly conditioned after Jacobi scaling
    K = np.diag([1e9, 1e3, 1.0])
    assert c.classify(K, what="K", symmetric=True, positive_definite=True).status is Status.OK
    # indefinite and well conditioned: not positive definite
    assert c.classify(np.diag([1.0, -1.0, 2.0]), what="K", symmetric=True,
                      positive_definite=True).status is Status.NOT_POSITIVE_DEFINITE
    # indefinite *and* singular: singular comes first
    assert c.classify(np.diag([1.0, -1.0, 0.0]), what="K", symmetric=True,
                      positive_definite=True).status is Status.SINGULAR


def test_non_finite_is_singular():
    assert c.classify(np.array([[np.nan, 0.0], [0.0, 1.0]]), what="A").status is Status.SINGULAR
    assert c.classify_rcond(float("nan"), what="A").status is Status.SINGULAR
    assert c.classify_rcond(1e-9, what="A").status is Status.ILL_CONDITIONED


def test_rcond_many_equals_rcond_bitwise():
    # the batched form against one matrix at a time (the reference): seeded matrices across the
    # bands, a zero matrix, a non-finite one and an exactly singular one
    rng = np.random.default_rng(3)
    mats = [rng.normal(size=(3, 3)) @ np.diag([1.0, 10.0 ** -rng.uniform(0, 14), 1.0]) for _ in range(60)]
    mats += [np.zeros((3, 3)), np.full((3, 3), np.nan), np.diag([1.0, np.inf, 1.0]), np.diag([1.0, 0.0, 2.0])]
    many = c.rcond_many(np.array(mats))
    one = np.array([c.rcond(A) for A in mats])
    assert np.array_equal(many, one)
    assert {c.classify_rcond(r, what="A").status for r in one} >= {Status.OK, Status.ILL_CONDITIONED, Status.SINGULAR}
