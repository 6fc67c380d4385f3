"""Pictures of the handle's results (matplotlib, Agg; called by ``--plots`` through the registry)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hapticopt.analysis.handle.model import N_PER_MM
from hapticopt.design.atomic import atomic_path


def _save(fig, target: Path) -> Path:
    import matplotlib.pyplot as plt

    with atomic_path(target) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return target


def zwidth_plots(design, result, out_dir: Path) -> list[Path]:
    """Stable / unstable cells of the Z-width map, the exact boundary and the paper's eq (18)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    zm = result.map
    B, K = zm.wall_damping_N_s_per_m, zm.wall_stiffness_N_per_m / N_PER_MM
    fig, ax = plt.subplots(figsize=(7, 4.8))
    ax.pcolormesh(B, K, zm.stable.T.astype(float), cmap="RdYlGn", vmin=-0.5, vmax=1.5, shading="nearest",
                  alpha=0.55)
    ok = np.isfinite(zm.boundary_N_per_m)
    ax.plot(B[ok], zm.boundary_N_per_m[ok] / N_PER_MM, "k-o", ms=3, label="exact sampled loop (boundary)")
    ax.plot(B, result.eq18_boundary_N_per_m / N_PER_MM, "b--", label="eq (18), Padé hold")
    ax.set_yscale("log")
    ax.set_ylim(K[0], K[-1])
    ax.set_xlabel("virtual damping B_e [N·s/m]")
    ax.set_ylabel("virtual stiffness K_e [N/mm] (shaft force per tip mm)")
    ax.set_title(f"{design.name}: Z-width, T = {design.firmware.period * 1e3:g} ms (green stable, red unstable)",
                 fontsize=10)
    ax.legend(loc="lower right", fontsize=8)
    return [_save(fig, out_dir / f"{design.name}_zwidth.png")]
