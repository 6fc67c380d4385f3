"""Full-length closed-loop checks of issue 8 on the multibody backend (docs/multibody.md):
every bundled scene at standard fidelity (FREE platform for the 3-PRRR) with its constraint health,
the master-transparency sweep vs the frequency-domain bandwidth, and stiffness-25 (lumped plant)
vs stiffness-25-links (multibody, real links + gravity): what link dynamics buys.

Run: ``.venv/bin/python scripts/accuracy/accuracy_mujoco_scenes.py`` (≈ 1–2 min on the 2-core machine).
"""

from __future__ import annotations

import os

from hapticopt.analysis import verify
from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.loop.scene import Backend, FirmwareMode, load_scene, scene_names
from hapticopt.design import io


def main() -> None:
    prrr, master = io.load_preset("prrr-paper"), io.load_preset("master-paper")
    print(f"load average {os.getloadavg()[0]:.1f}")
    print("| scene | fidelity | backend | status | violation mm | rotation mrad | health ok | key metric | wall s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in scene_names():
        sc = load_scene(name)
        if sc.controller.mode != FirmwareMode.IMPEDANCE and sc.device != "master":
            continue  # the 3-PRRR's IOIC mode runs on the lumped plant only (scripts/accuracy/accuracy_seed001_devices.py)
        design = master if sc.device == "master" else prrr
        for fid in (Fidelity.DRAFT, Fidelity.STANDARD):
            r = verify.simulate(design, sc, fidelity=fid, backend=Backend.MULTIBODY)
            m = r.metrics()
            key = ""
            for k in ("bandwidth_error_pct", "rendered_wall_stiffness_N_per_mm", "rendered_stiffness_N_per_mm",
                      "residual_force_rms_N", "wall_penetration_mm"):
                if m.get(k) is not None:
                    key = f"{k} {m[k]:.4g}"
                    if k == "bandwidth_error_pct":
                        key += f" ({m['transparency_bandwidth_Hz']:.4g} vs {m['predicted_bandwidth_Hz']:.4g} Hz)"
                    break
            print(f"| {name} | {fid.value} | {m['backend']} | {r.status} | {m['constraint_violation_mm']:.3g} | "
                  f"{m.get('ee_rotation_mrad', 0.0):.3g} | {m['constraint_health_ok']} | {key} | {m['wall_time_s']:.2f} |",
                  flush=True)
    lumped = verify.simulate(prrr, load_scene("stiffness-25")).metrics()
    links = verify.simulate(prrr, load_scene("stiffness-25-links")).metrics()
    print(f"stiffness-25 lumped: K {lumped['rendered_stiffness_N_per_mm']:.4f} N/mm, residual "
          f"{lumped['residual_force_rms_N']:.3f} N; stiffness-25-links multibody: K "
          f"{links['rendered_stiffness_N_per_mm']:.4f} N/mm, residual {links['residual_force_rms_N']:.3f} N")


if __name__ == "__main__":
    main()
