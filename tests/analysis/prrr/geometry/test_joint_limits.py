"""hapticopt.analysis.prrr.geometry.joint_limits: the batched draft evaluator's ranges (in-plane IK, numpy and jax)
and result step equal the per-design ones on the IK of every grid point."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import jax.numpy as jnp

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr.geometry import joint_limits as JL
from hapticopt.analysis.prrr.geometry.workspace import ELBOW_BRANCH
from hapticopt.analysis.status import Status
from hapticopt.design import io
from hapticopt.design.prrr.kinematics import inverse_kinematics, params_np

BASE = io.load_preset("prrr-paper")


def _designs() -> list:
    """The preset (ok), d2 = 300 mm (no grid point in reach: empty), and seeded layouts around the
    preset (partly out of reach, or a limit cutting the cylinder: not-met)."""
    rng = np.random.default_rng(15)
    g = BASE.geometry
    out = [BASE, dataclasses.replace(BASE, geometry=dataclasses.replace(g, d2=0.300))]
    for _ in range(10):
        out.append(dataclasses.replace(BASE, geometry=dataclasses.replace(
            g, d3=g.d3 * rng.uniform(0.8, 1.2), d4=g.d4 * rng.uniform(0.8, 1.2), stroke=g.stroke * rng.uniform(0.6, 1.2))))
    return out


def _grid(d, radius, n_phi=24, n_r=6, n_z=3):
    """The cylinder grid written out (the module's rim-and-axis grid: φ_i = 2πi/n_φ, r_j = R j/n_r, heights
    ±(H/2)(1 − 1e-9) with H = L − 2R cot β; the axis at each height last)."""
    g = d.geometry
    h = max(g.stroke - 2.0 * radius / np.tan(g.beta), 0.0)
    z = np.linspace(-h / 2, h / 2, n_z) * (1.0 - 1e-9)
    phi = np.repeat(np.linspace(0.0, 2.0 * math.pi, n_phi, endpoint=False), n_r * n_z)  # φ-major order
    r = np.tile(np.repeat(np.linspace(0.0, radius, n_r + 1)[1:], n_z), n_phi)
    return np.concatenate([np.stack([r * np.cos(phi), r * np.sin(phi), np.tile(z, n_phi * n_r)], axis=1),
                           np.stack([np.zeros(n_z), np.zeros(n_z), z], axis=1)])


def _full_grid(d):
    """The reference: the numpy IK of every cylinder grid point."""
    ik = inverse_kinematics(params_np(d), _grid(d, JL.FW.DEFAULT_REQUIRED_DIAMETER / 2.0), xp=np)
    return np.asarray(ik.theta)[:, ELBOW_BRANCH], np.asarray(ik.reachable)


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert np.array_equal(np.isfinite(a), np.isfinite(b)) and np.array_equal(a[~np.isfinite(a)], b[~np.isfinite(b)])
    fin = np.isfinite(b)
    return float(np.max(np.abs(a[fin] - b[fin]) / np.abs(b[fin]), initial=0.0))


def test_grid_size_counts_the_cylinder_grid():
    assert JL.grid_size() == len(_grid(BASE, 0.07)) == 435


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_cylinder_ranges_equal_the_reductions_of_every_grid_point(xp):
    """The ranges from the in-plane IK at z = 0 (the angles do not depend on the height) against the
    masked reductions of the numpy IK of every grid point: equal counts out of
    reach, extremes to 1e-12 relative (rounding: the two compute the same angles by different sums)."""
    designs = _designs()
    n_out = set()
    for d in designs:
        th, ok = _full_grid(d)
        got = JL.cylinder_ranges_of(params_np(d), JL.FW.DEFAULT_REQUIRED_DIAMETER / 2.0, xp=xp)
        assert int(got.n_out) == int((~ok).sum())
        n_out.add(int(got.n_out))
        if ok.any():
            ref_lo, ref_hi = th[ok].min(axis=(0, 1)), th[ok].max(axis=(0, 1))
            ref_top = np.abs(th[ok][..., 1]).max()
        else:
            ref_lo, ref_hi, ref_top = np.full(3, np.inf), np.full(3, -np.inf), -np.inf
        assert _rel(got.lo, ref_lo) <= 1e-12 and _rel(got.hi, ref_hi) <= 1e-12 and _rel(got.top, ref_top) <= 1e-12
    assert 0 in n_out and JL.grid_size() in n_out and len(n_out) > 2  # in reach, none in reach, partly


def test_evaluate_is_the_batch_of_one_and_the_full_grids_verdict():
    """``evaluate`` (one design: ``cylinder_ranges_of`` in numpy, then ``from_ranges_many``) gives the batch's
    result bit for bit, and the verdict of the full grid's angles (the reference: ``th[ok]`` reduced over
    points and legs; ranges and margin to 1e-12 relative, statuses and messages equal)."""
    designs = _designs()
    ranges = [JL.cylinder_ranges_of(params_np(d), JL.FW.DEFAULT_REQUIRED_DIAMETER / 2.0, xp=np) for d in designs]
    stacked = JL.JointRanges(*(np.stack([np.asarray(getattr(r, f)) for r in ranges]) for f in JL.JointRanges._fields))
    many = JL.from_ranges_many(designs, stacked, n_points=JL.grid_size(), fidelity=Fidelity.DRAFT, t0=0.0)
    statuses = set()
    for d, got in zip(designs, many, strict=True):
        th, ok = _full_grid(d)
        statuses.add(got.status)
        if not ok.any():
            assert got.status is Status.EMPTY
            continue
        one = JL.evaluate(d, fidelity=Fidelity.DRAFT)
        assert (one.status, one.message, one.used, one.margin) == (got.status, got.message, got.used, got.margin)
        sel = th[ok]
        lo, hi = sel.min(axis=(0, 1)), sel.max(axis=(0, 1))
        for j in range(3):
            assert _rel(got.used[f"r{j + 1}"], (lo[j], hi[j])) <= 1e-12
        margin = JL.elbow_limit(d) - float(np.abs(sel[..., 1]).max())
        assert abs(got.margin - margin) <= 1e-12 * abs(margin)
        assert (got.status is Status.OK) == (bool(ok.all()) and margin >= 0.0)
    assert statuses == {Status.OK, Status.EMPTY, Status.NOT_MET}
