"""hapticopt.analysis.prrr.joint_limits: the batched draft evaluator's ranges (in-plane IK, numpy and jax)
and result step equal the per-design ones on the IK of every grid point."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import jax.numpy as jnp

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr import joint_limits as JL
from hapticopt.analysis.prrr.workspace import ELBOW_BRANCH
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


def _full_grid(d):
    """The reference: the numpy IK of every cylinder grid point (the single path's angles)."""
    ik = inverse_kinematics(params_np(d), JL.cylinder_grid(d, JL.FW.DEFAULT_REQUIRED_DIAMETER / 2.0), xp=np)
    return np.asarray(ik.theta)[:, ELBOW_BRANCH], np.asarray(ik.reachable)


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert np.array_equal(np.isfinite(a), np.isfinite(b)) and np.array_equal(a[~np.isfinite(a)], b[~np.isfinite(b)])
    fin = np.isfinite(b)
    return float(np.max(np.abs(a[fin] - b[fin]) / np.abs(b[fin]), initial=0.0))


def test_grid_size_counts_the_cylinder_grid():
    assert JL.grid_size() == len(JL.cylinder_grid(BASE, 0.07)) == 435


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_cylinder_ranges_equal_the_reductions_of_every_grid_point(xp):
    """The ranges from the in-plane IK at z = 0 (the angles do not depend on the height) against the
    masked reductions of the numpy IK of every grid point (``from_angles``' own): equal counts out of
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


def test_from_ranges_many_equals_from_angles():
    designs = _designs()
    refs, ranges = [], []
    for d in designs:
        th, ok = _full_grid(d)
        refs.append(JL.from_angles(d, th, ok, fidelity=Fidelity.DRAFT, t0=0.0))  # the reference: one design
        ranges.append(JL.cylinder_ranges_of(params_np(d), JL.FW.DEFAULT_REQUIRED_DIAMETER / 2.0, xp=np))
    stacked = JL.JointRanges(*(np.stack([np.asarray(getattr(r, f)) for r in ranges]) for f in JL.JointRanges._fields))
    many = JL.from_ranges_many(designs, stacked, n_points=JL.grid_size(), fidelity=Fidelity.DRAFT, t0=0.0)
    statuses = set()
    for got, ref in zip(many, refs, strict=True):
        assert (got.status, got.message) == (ref.status, ref.message)
        assert got.used.keys() == ref.used.keys() and got.elbow_limit == ref.elbow_limit
        for j in ref.used:
            assert _rel(got.used[j], ref.used[j]) <= 1e-12
        assert abs(got.margin - ref.margin) <= 1e-12 * abs(ref.margin) or (math.isnan(got.margin) and math.isnan(ref.margin))
        statuses.add(ref.status)
    assert statuses == {Status.OK, Status.EMPTY, Status.NOT_MET}


def test_cylinder_grid_is_the_polar_grid_and_its_cached_xy_stays_unchanged():
    """cylinder_grid's points (its x, y made once per radius and counts) equal the polar grid written out
    (the module docstring's rim-and-axis grid: φ_i = 2πi/n_φ, r_j = R j/n_r, heights ±(H/2)(1 − 1e-9)
    with H = L − 2R cot β), bit for bit, for two designs in turn (the second reuses the cached x, y),
    and the cached arrays cannot be written."""
    n_phi, n_r, n_z, radius = 24, 6, 3, 0.07
    for d in _designs()[:2] + _designs()[:1]:
        g = d.geometry
        h = max(g.stroke - 2.0 * radius / np.tan(g.beta), 0.0)
        z = np.linspace(-h / 2, h / 2, n_z) * (1.0 - 1e-9)
        phi = np.repeat(np.linspace(0.0, 2.0 * math.pi, n_phi, endpoint=False), n_r * n_z)  # φ-major order
        r = np.tile(np.repeat(np.linspace(0.0, radius, n_r + 1)[1:], n_z), n_phi)
        want = np.concatenate([np.stack([r * np.cos(phi), r * np.sin(phi), np.tile(z, n_phi * n_r)], axis=1),
                               np.stack([np.zeros(n_z), np.zeros(n_z), z], axis=1)])
        got = JL.cylinder_grid(d, radius, n_phi=n_phi, n_r=n_r, n_z=n_z)
        assert got.shape == want.shape and got.tobytes() == want.tobytes()
    x, _ = JL._grid_xy(radius, n_phi, n_r, n_z)
    assert not x.flags.writeable


def test_from_angles_ranges_are_the_reachable_angles_extremes():
    """from_angles' joint ranges and elbow margin are the minimum and maximum over the reachable points'
    angles and their largest |θ2| (the reference: ``th[ok]`` reduced over points and legs), exactly,
    for the sample's designs (ok, not-met and partly reachable among them)."""
    n = 0
    for d in _designs():
        ik = inverse_kinematics(params_np(d), JL.cylinder_grid(d, JL.FW.DEFAULT_REQUIRED_DIAMETER / 2.0), xp=np)
        th, ok = np.asarray(ik.theta)[:, ELBOW_BRANCH], np.asarray(ik.reachable)
        got = JL.from_angles(d, th, ok, fidelity=Fidelity.DRAFT, t0=0.0)
        if not ok.any():
            assert got.status is Status.EMPTY
            continue
        sel = th[ok]
        lo, hi = sel.min(axis=(0, 1)), sel.max(axis=(0, 1))
        assert got.used == {f"r{j + 1}": (float(lo[j]), float(hi[j])) for j in range(3)}
        assert got.margin == JL.elbow_limit(d) - float(np.abs(sel[..., 1]).max())
        n += 1
    assert n >= 5
