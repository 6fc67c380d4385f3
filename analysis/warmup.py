"""Compile the numba kernels into numba's on-disk cache once, at setup (``make setup``; the Makefile's
install step runs ``python -m hapticopt.analysis.warmup``).

A kernel's first call in a fresh install compiles it (tens of seconds for the collision check's kernel);
every later process loads the compiled code from the cache. Done here, a user's first ``make run`` and the
first test run do not pay the compile. Running it again only loads the cache. A kernel that cannot
run here (numba missing, no writable cache folder) is reported with its reason; the numpy / Python
reference paths then run, so this never fails the install.
"""

from __future__ import annotations

import time

import numpy as np

from hapticopt.analysis.prrr.loop import mujoco_plant as prrr_mujoco
from hapticopt.analysis.compute import Compute
from hapticopt.analysis.prrr.structure import frame_condense, frame_model
from hapticopt.analysis.prrr.collision import interference_fast
from hapticopt.design import io


def warm() -> list[tuple[str, str | None, float]]:
    """(kernel, None or why it is unavailable, seconds) for the collision check, the MuJoCo loops and the
    batched frame condensation."""
    out = []
    t0 = time.perf_counter()
    reason = interference_fast.availability()
    if reason is None:
        model = interference_fast.prepare(io.load_preset("prrr-paper"))
        interference_fast.check_points(model, np.array([[0.0, 0.0, 0.0]]))
        # the batched check's compiled IK (one pose)
        geo = {f: np.array([float(getattr(model.design.geometry, f))]) for f in interference_fast.IK_FIELDS}
        joints = (np.empty((1, 3)),) + tuple(np.empty((1, 3)) for _ in range(4)) + (np.empty(1, bool),)
        interference_fast.pose_joints(np.zeros(1, int), np.zeros(1, int), np.zeros((1, 3)), geo, 0, joints)
    out.append(("collision check", reason, time.perf_counter() - t0))
    t0 = time.perf_counter()
    out.append(("MuJoCo closed loops", prrr_mujoco.warm_up(), time.perf_counter() - t0))
    t0 = time.perf_counter()
    reason = frame_condense.kernel_availability()
    if reason is None:  # the batched draft evaluator's frame assembly and condensation (one design's legs)
        options = frame_model.FrameOptions()
        fp = frame_model.frame_params_of(io.load_preset("prrr-paper"), xp=np)
        G, Ks, P, _ = frame_model.frame_leg_terms(fp, np.zeros(3), options, xp=np)
        frame_condense.condense_terms_many(G[None], Ks[None], P[None], options, frame_model.LOAD_HEIGHT,
                                           compute=Compute(backend="numba"))
    out.append(("frame condensation", reason, time.perf_counter() - t0))
    return out


def main() -> None:
    for name, reason, seconds in warm():
        state = "ready" if reason is None else f"not compiled: {reason} (the reference path runs)"
        print(f"warm-up: {name} {state} ({seconds:.1f} s)")


if __name__ == "__main__":
    main()
