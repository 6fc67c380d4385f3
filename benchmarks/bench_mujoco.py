"""Multibody plant benchmarks.

Targets (2-core CPU): the 3 s ``stiffness-25`` scene on the MuJoCo plant ≥ 10× real time;
the closed-loop overhead over raw ``mj_step`` at the same substeps ≤ 1.5×. Both are reported as
extra_info (``real_time_factor``, ``loop_overhead``, wall and process-CPU figures, the load
average — the machine is shared, so CPU time is the closer estimate of an idle machine); no
timed asserts. Draft (0.25 ms Euler) and standard (0.1 ms Euler) fidelity, FREE and
TRANSLATIONAL platform; the master-wall and master-protocol-x (dynamics compensation) scenes on the MuJoCo master.
The loop-overhead tests run the compiled loop, the Python loop and raw ``mj_step`` interleaved in one process
and report the medians of the per-round ratios (docs/performance.md's MuJoCo table).
"""

from __future__ import annotations

import dataclasses
import os
import statistics
import time

import mujoco
import pytest

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.compute import Compute
from hapticopt.analysis.loop.scene import Backend, Effect, load_scene, resolve
from hapticopt.analysis.master import mujoco_plant as mm
from hapticopt.analysis.prrr.loop import closed_loop
from hapticopt.analysis.prrr.loop.firmware import ScalarController
from hapticopt.analysis.prrr.loop.mujoco_model import Platform, build, set_pose
from hapticopt.analysis.prrr.loop.mujoco_plant import MujocoPlant, model_options, simulate
from hapticopt.design import io

DESIGN = io.load_preset("prrr-paper")


def _raw_mj_step(scene, platform: Platform, fidelity: Fidelity) -> tuple[float, float]:
    """Raw mj_step of the same model (energy on, as in the loop) for the scene's duration: (wall, CPU) [s]."""
    res = resolve(scene, force=Backend.MULTIBODY)
    opts = model_options(scene, res, fidelity=fidelity, platform=platform)
    mj = build(DESIGN, opts)
    mj.model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    data = mujoco.MjData(mj.model)
    set_pose(mj, data, [0.0, 0.0, 0.0])
    n = int(round(scene.controller.period / mj.model.opt.timestep))
    ticks = int(round(scene.duration / scene.controller.period))
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(ticks):
        mujoco.mj_step(mj.model, data, nstep=n)
    return time.perf_counter() - t0, time.process_time() - c0


def _bench(benchmark, platform: Platform, fidelity: Fidelity) -> None:
    scene = load_scene("stiffness-25")
    results, cpu = [], []

    def once():
        c0 = time.process_time()
        results.append(simulate(DESIGN, scene, platform=platform, fidelity=fidelity))
        cpu.append(time.process_time() - c0)

    benchmark.pedantic(once, rounds=5, iterations=1)
    raws = [_raw_mj_step(scene, platform, fidelity) for _ in range(5)]
    loop = statistics.median(r.wall_time for r in results)
    raw = statistics.median(w for w, _ in raws)
    raw_cpu = statistics.median(c for _, c in raws)
    benchmark.extra_info.update(
        real_time_factor=scene.duration / loop, loop_s=loop, raw_mj_step_s=raw, loop_overhead=loop / raw,
        loop_cpu_s_incl_build=statistics.median(cpu), raw_mj_step_cpu_s=raw_cpu,
        substeps=results[0].substeps, violation_mm=results[0].health.violation * 1e3,
        load_average=os.getloadavg()[0],
    )


@pytest.mark.parametrize("fidelity", [Fidelity.DRAFT, Fidelity.STANDARD], ids=lambda f: f.value)
def test_stiffness_25_free_platform(benchmark, fidelity):
    _bench(benchmark, Platform.FREE, fidelity)


@pytest.mark.parametrize("fidelity", [Fidelity.DRAFT, Fidelity.STANDARD], ids=lambda f: f.value)
def test_stiffness_25_translational_platform(benchmark, fidelity):
    _bench(benchmark, Platform.TRANSLATIONAL, fidelity)


def test_master_wall(benchmark):
    master = io.load_preset("master-paper")
    scene = load_scene("master-wall")
    out = []
    benchmark.pedantic(lambda: out.append(mm.simulate(master, scene)), rounds=3, iterations=1)
    wall = statistics.median(r.wall_time for r in out)
    benchmark.extra_info.update(real_time_factor=scene.duration / wall, wall_s=wall, load_average=os.getloadavg()[0])


def _raw(m, d, ticks: int, nstep: int) -> float:
    """Raw ``mj_step`` from Python, once per tick with ``nstep`` substeps (the loops' physics alone) [s]."""
    t0 = time.perf_counter()
    for _ in range(ticks):
        mujoco.mj_step(m, d, nstep=nstep)
    return time.perf_counter() - t0


def _master_loop_and_raw(fidelity: Fidelity, rounds: int = 5, scene_name: str = "master-wall",
                         python_ticks: int | None = None) -> dict[str, list[float]]:
    """A master scene's closed loop (``MasterPlant.run``) compiled and in Python, and raw ``mj_step`` of the same
    model for the same ticks and substeps, interleaved: {"compiled", "python", "raw", "raw_python"} walls [s].

    ``python_ticks``: the Python loop runs only that many ticks (the compensation scenes' Python loop costs ≈ 1 ms a
    tick), against raw mj_step over the same ticks ("raw_python"); None: the scene's ticks."""
    master = io.load_preset("master-paper")
    scene = load_scene(scene_name)
    res = resolve(scene)
    T = scene.controller.period
    plant = mm.MasterPlant(master, scene, res, period=T, fidelity=fidelity)
    N = int(round(scene.duration / T))
    Np = N if python_ticks is None else min(N, python_ticks)
    out: dict[str, list[float]] = {"compiled": [], "python": [], "raw": [], "raw_python": []}
    kw = dict(frequency=scene.motion.frequency, quantize=Effect.QUANTIZATION in res.effects)
    spring = plant.model.qpos_spring.copy()  # the loops write the hand reference there; raw starts from the model's
    plant.run(mm.controller_for(master, scene, res, plant.x0, plant.q0, T), ticks=10, frequency=1.0,
              quantize=True)  # load the compiled kernel outside the timing

    def loop(engine: str, n: int) -> None:
        ctl = mm.controller_for(master, scene, res, plant.x0, plant.q0, T)
        t0 = time.perf_counter()
        plant.run(ctl, ticks=n, compute=Compute(backend="numba" if engine == "compiled" else "numpy"), **kw)
        out[engine].append(time.perf_counter() - t0)
        assert plant.loop_engine == engine, plant.loop_reason

    def raw(n: int) -> float:
        plant.model.qpos_spring[:] = spring
        plant.reset()
        return _raw(plant.model, plant.data, n, plant.substeps)

    for r in range(rounds):
        # the compiled loop and its raw baseline back to back, their order alternating by round (an order effect
        # cancels in the median); the Python loop and its own raw baseline after them
        if r % 2:
            out["raw"].append(raw(N))
            loop("compiled", N)
        else:
            loop("compiled", N)
            out["raw"].append(raw(N))
        loop("python", Np)
        out["raw_python"].append(out["raw"][-1] if Np == N else raw(Np))
    return out


def _prrr_loop_and_raw(fidelity: Fidelity, rounds: int = 5) -> dict[str, list[float]]:
    """The stiffness-25 closed loop (``MujocoPlant.run``, FREE platform) compiled and in Python, and raw
    ``mj_step`` of the same model (energy on) for the same ticks and substeps, interleaved [s]."""
    scene = load_scene("stiffness-25")
    ch = resolve(scene, force=Backend.MULTIBODY)
    st = closed_loop.setup(DESIGN, dataclasses.replace(scene, effects=scene.effects - {Effect.LINK_DYNAMICS}),
                           fidelity=fidelity)
    plant = MujocoPlant(DESIGN, scene, model_options(scene, ch, fidelity=fidelity, platform=Platform.FREE),
                        period=st.period, interpolation=st.cfg.interpolation)
    plant.enable_energy()
    st = dataclasses.replace(st, resolution=ch, substeps=plant.substeps)
    out: dict[str, list[float]] = {"compiled": [], "python": [], "raw": []}
    plant.run(ScalarController(st.cfg, st.gains), dataclasses.replace(st, ticks=10))  # load the kernel
    for _ in range(rounds):
        for engine in ("compiled", "python"):
            ctl = ScalarController(st.cfg, st.gains)
            t0 = time.perf_counter()
            plant.run(ctl, st, compute=Compute(backend="numba" if engine == "compiled" else "numpy"))
            out[engine].append(time.perf_counter() - t0)
            assert plant.loop_engine == engine, plant.loop_reason
        plant.reset()
        out["raw"].append(_raw(plant.model, plant.data, st.ticks, plant.substeps))
    return out


def _ratios(out: dict[str, list[float]]) -> dict[str, float]:
    """Medians of the per-round ratios (each round's loops and raw run back to back: a load change between rounds
    cancels) and of the walls."""
    med = {k: statistics.median(v) for k, v in out.items()}
    rounds = {e: [a / r for a, r in zip(out[e], out["raw_python" if e == "python" and "raw_python" in out else "raw"])]
              for e in ("compiled", "python")}
    per = {e: statistics.median(v) for e, v in rounds.items()}
    q = statistics.quantiles(rounds["compiled"], n=4) if len(rounds["compiled"]) > 1 else [per["compiled"]] * 3
    return {"compiled_over_raw": per["compiled"], "python_over_raw": per["python"],
            "compiled_over_raw_quartiles": (q[0], q[2]),
            "compiled_s": med["compiled"], "python_s": med["python"], "raw_mj_step_s": med["raw"],
            "load_average": os.getloadavg()[0]}


@pytest.mark.parametrize("fidelity", [Fidelity.DRAFT, Fidelity.STANDARD], ids=lambda f: f.value)
def test_master_loop_overhead(benchmark, fidelity):
    """The master's closed loop over raw mj_step on the same model (target ≤ 1.10×), compiled and Python, side by
    side (docs/performance.md)."""
    out = benchmark.pedantic(lambda: _master_loop_and_raw(fidelity), rounds=1, iterations=1)
    benchmark.extra_info.update(_ratios(out))


@pytest.mark.parametrize("fidelity", [Fidelity.DRAFT, Fidelity.STANDARD], ids=lambda f: f.value)
def test_master_protocol_loop_overhead(benchmark, fidelity):
    """master-protocol-x (dynamics compensation, 4 kHz, one plant step a tick) over raw mj_step (target ≤ 1.10×),
    compiled over the scene's 12000 ticks, Python over 1000 (against raw mj_step over the same 1000)."""
    out = benchmark.pedantic(lambda: _master_loop_and_raw(fidelity, scene_name="master-protocol-x", python_ticks=1000),
                             rounds=1, iterations=1)
    benchmark.extra_info.update(_ratios(out))


@pytest.mark.parametrize("fidelity", [Fidelity.DRAFT, Fidelity.STANDARD], ids=lambda f: f.value)
def test_prrr_loop_overhead(benchmark, fidelity):
    """The 3-PRRR's closed loop (stiffness-25, FREE) over raw mj_step on the same model (target ≤ 1.10×), compiled
    and Python, side by side (docs/performance.md)."""
    out = benchmark.pedantic(lambda: _prrr_loop_and_raw(fidelity), rounds=1, iterations=1)
    benchmark.extra_info.update(_ratios(out))

