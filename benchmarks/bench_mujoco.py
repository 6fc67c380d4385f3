"""Multibody plant benchmarks (issue 8).

Targets (2-core CPU): the 3 s ``stiffness-25`` scene on the MuJoCo plant ≥ 10× real time;
the closed-loop overhead over raw ``mj_step`` at the same substeps ≤ 1.5×. Both are reported as
extra_info (``real_time_factor``, ``loop_overhead``); no timed asserts.
"""

from __future__ import annotations

import time

import mujoco

import analysis  # noqa: F401
from analysis.fidelity import Fidelity
from analysis.mujoco_plant import model_options, simulate, choose_backend
from analysis.mujoco_prrr import Platform, build, set_pose
from analysis.scene import Backend, load_scene
from design import io

DESIGN = io.load_preset("prrr-paper")


def _raw_mj_step_s(scene, platform: Platform) -> float:
    """Raw mj_step of the same model for the scene's duration (nstep = substeps per tick)."""
    res = choose_backend(scene, force=Backend.MULTIBODY).resolution
    opts = model_options(scene, res, fidelity=Fidelity.STANDARD, platform=platform)
    mj = build(DESIGN, opts)
    data = mujoco.MjData(mj.model)
    set_pose(mj, data, [0.0, 0.0, 0.0])
    n = int(round(scene.controller.period / mj.model.opt.timestep))
    ticks = int(round(scene.duration / scene.controller.period))
    t0 = time.perf_counter()
    for _ in range(ticks):
        mujoco.mj_step(mj.model, data, nstep=n)
    return time.perf_counter() - t0


def _bench(benchmark, platform: Platform) -> None:
    scene = load_scene("stiffness-25")
    results = []
    benchmark.pedantic(lambda: results.append(simulate(DESIGN, scene, platform=platform)), rounds=3, iterations=1)
    loop = min(r.wall_time for r in results)
    raw = min(_raw_mj_step_s(scene, platform) for _ in range(3))
    benchmark.extra_info.update(
        real_time_factor=scene.duration / loop, loop_s=loop, raw_mj_step_s=raw, loop_overhead=loop / raw,
        substeps=results[0].substeps, violation_mm=results[0].health.violation * 1e3,
    )


def test_stiffness_25_free_platform(benchmark):
    _bench(benchmark, Platform.FREE)


def test_stiffness_25_translational_platform(benchmark):
    _bench(benchmark, Platform.TRANSLATIONAL)
