"""hapticopt.analysis.prrr.joint_limits: the batched result step equals the per-design one."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr import joint_limits as JL
from hapticopt.analysis.prrr.workspace import ELBOW_BRANCH
from hapticopt.analysis.status import Status
from hapticopt.design import io
from hapticopt.design.prrr.kinematics import inverse_kinematics, params_of

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


def test_from_angles_many_equals_from_angles():
    designs = _designs()
    th, ok = [], []
    for d in designs:
        ik = inverse_kinematics(params_of(d), JL.cylinder_grid(d, JL.FW.DEFAULT_REQUIRED_DIAMETER / 2.0))
        th.append(np.asarray(ik.theta)[:, ELBOW_BRANCH])
        ok.append(np.asarray(ik.reachable))
    many = JL.from_angles_many(designs, np.stack(th), np.stack(ok), fidelity=Fidelity.DRAFT, t0=0.0)
    statuses = set()
    for d, t, o, got in zip(designs, th, ok, many):
        ref = JL.from_angles(d, t, o, fidelity=Fidelity.DRAFT, t0=0.0)  # the reference: one design
        assert (got.status, got.message) == (ref.status, ref.message)
        assert got.used == ref.used and got.elbow_limit == ref.elbow_limit
        assert got.margin == ref.margin or (math.isnan(got.margin) and math.isnan(ref.margin))
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
        ik = inverse_kinematics(params_of(d), JL.cylinder_grid(d, JL.FW.DEFAULT_REQUIRED_DIAMETER / 2.0))
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
