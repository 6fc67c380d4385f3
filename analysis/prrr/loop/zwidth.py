"""Z-width: the stable (K_v, B_v) region of the virtual environment along one axis.

Every point is one closed-loop run of the scene (e.g. the bundled ``z-width`` scene: released
1 mm off the anchor, nobody holding the handle, decay criterion). All points of a map run as
one batched, compiled simulation (:class:`hapticopt.analysis.prrr.loop.closed_loop.Simulator` batched over gains);
the boundary K_max(B) is refined by bisection, all damping values at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hapticopt.analysis.prrr.loop.closed_loop import Simulator, batch_gains, classify, setup
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.loop.scene import Scene
from hapticopt.design.prrr.params import PrrrDesign


@dataclass(frozen=True, kw_only=True)
class ZWidthMap:
    axis: int
    stiffness: np.ndarray  # (nK,) [N/m]
    damping: np.ndarray  # (nB,) [N·s/m]
    stable: np.ndarray  # (nB, nK) bool
    boundary: np.ndarray | None = None  # (nB,) largest stable K per damping [N/m] (bisection)

    def metrics(self) -> dict[str, object]:
        out: dict[str, object] = {
            "zwidth_axis": "xyz"[self.axis],
            "zwidth_stable_fraction": float(self.stable.mean()),
            "zwidth_stiffness_N_per_mm": [float(k) * 1e-3 for k in self.stiffness],
            "zwidth_damping_Ns_per_m": [float(b) for b in self.damping],
            "zwidth_stable": [[bool(s) for s in row] for row in self.stable],
        }
        if self.boundary is not None:
            out["zwidth_boundary_N_per_mm"] = [float(k) * 1e-3 for k in self.boundary]
        return out


class StabilityProbe:
    """Classifies batches of (K_v, B_v) on one axis as stable/unstable with one compiled run each."""

    def __init__(self, design: PrrrDesign, scene: Scene, *, fidelity: Fidelity = Fidelity.STANDARD,
                 axis: int | None = None, **gain_overrides: float) -> None:
        self.st = setup(design, scene, fidelity=fidelity)
        self.axis = scene.zwidth.axis if axis is None else axis
        self.sim = Simulator(self.st, record=False)
        self.overrides = gain_overrides

    def __call__(self, stiffness: np.ndarray, damping: np.ndarray) -> np.ndarray:
        K = np.zeros((len(stiffness), 3))
        B = np.zeros((len(stiffness), 3))
        K[:, self.axis], B[:, self.axis] = stiffness, damping
        extra = {k: np.full(len(stiffness), v) for k, v in self.overrides.items()}
        gains = batch_gains(self.st.gains, stiffness=K, damping=B, **extra)
        tr = self.sim.run(gains, batch=len(stiffness))
        stable, _ = classify(tr, self.st)
        return stable


def bisect_boundary(probe: StabilityProbe, damping: np.ndarray, lo: float, hi: float, *, iters: int = 12
                    ) -> np.ndarray:
    """Largest stable K per damping value in [lo, hi] [N/m] (geometric bisection, all B at once).

    Returns ``lo`` where even ``lo`` is unstable and ``hi`` where ``hi`` is still stable.
    """
    damping = np.asarray(damping, dtype=float)
    a = np.full(len(damping), float(lo))
    b = np.full(len(damping), float(hi))
    ok_lo = probe(a, damping)
    ok_hi = probe(b, damping)
    for _ in range(iters):
        mid = np.sqrt(a * b)
        ok = probe(mid, damping)
        a = np.where(ok, mid, a)
        b = np.where(ok, b, mid)
    out = np.sqrt(a * b)
    out = np.where(ok_hi, hi, out)
    return np.where(ok_lo, out, lo)


def zwidth_map(design: PrrrDesign, scene: Scene, *, fidelity: Fidelity = Fidelity.STANDARD,
               boundary: bool = False) -> ZWidthMap:
    """Stable grid over the scene's [zwidth] ranges (points × points, one batched run)."""
    z = scene.zwidth
    Ks = np.geomspace(*z.stiffness_range, z.points) if z.stiffness_range[0] > 0 else np.linspace(
        *z.stiffness_range, z.points)
    Bs = np.linspace(*z.damping_range, z.points)
    probe = StabilityProbe(design, scene, fidelity=fidelity)
    KK, BB = np.meshgrid(Ks, Bs)
    stable = probe(KK.ravel(), BB.ravel()).reshape(KK.shape)
    bnd = bisect_boundary(probe, Bs, max(Ks[0], 1.0), Ks[-1]) if boundary else None
    return ZWidthMap(axis=z.axis, stiffness=Ks, damping=Bs, stable=stable, boundary=bnd)
