"""The compiled MuJoCo closed loops (analysis/loop/mujoco_compiled.py) against the Python loops they replace.

The reference is each plant's own Python loop (``run(..., compiled=False)``): the compiled loop must give the
same records bit for bit (the requirement is ≤ 1e-12 relative; the law is mirrored operation by operation,
so equality is exact), the same stop tick, saturation flags, constraint health and status. Scenes: the five
3-PRRR scenes and the master scenes of docs/performance.md, draft and standard, shortened to 0.3 s.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.loop import mujoco_compiled as mc
from hapticopt.analysis.loop.scene import Backend, Effect, load_scene
from hapticopt.analysis.prrr import closed_loop
from hapticopt.analysis.prrr import mujoco_plant as prrr_mj
from hapticopt.analysis.prrr.firmware_numpy import NumpyController
from hapticopt.analysis.prrr.mujoco_model import Platform
from hapticopt.analysis.master import mujoco_plant as master_mj
from hapticopt.analysis.master.firmware import MasterController
from hapticopt.design.io import load_preset

PRRR = load_preset("prrr-paper")
MASTER = load_preset("master-paper")
PRRR_SCENES = ["stiffness-25", "free-space", "virtual-box", "free-space-x", "stiffness-25-links"]
FIDELITIES = [Fidelity.DRAFT, Fidelity.STANDARD]
TRACE_KEYS = ("position", "velocity", "hand_force", "actuator_force", "force_reference", "energy")


def test_compiled_loops_are_available_here():
    """numba, libmujoco and the mjData layout check out on this machine (else every run falls back)."""
    assert mc.availability() is None
    lay = mc.layout()
    assert lay.ne < lay.nefc < lay.time < lay.efc_pos  # info header, then the pointer fields


def _prrr_plant(scene, fidelity):
    ch = prrr_mj.choose_backend(scene, force=Backend.MULTIBODY)
    st = closed_loop.setup(PRRR, dataclasses.replace(scene, effects=scene.effects - {Effect.LINK_DYNAMICS}),
                           fidelity=fidelity)
    plant = prrr_mj.MujocoPlant(PRRR, scene, prrr_mj.model_options(scene, ch.resolution, fidelity=fidelity,
                                                                   platform=Platform.FREE), period=st.period)
    plant.enable_energy()
    return plant, dataclasses.replace(st, substeps=plant.substeps)


def _assert_same_traces(a, b):
    for k in TRACE_KEYS:
        x, y = getattr(a, k), getattr(b, k)
        np.testing.assert_array_equal(x, y, err_msg=k)  # bit-identical (stronger than ≤ 1e-12 relative)
    assert a.stop_tick[0] == b.stop_tick[0]
    np.testing.assert_array_equal(a.saturated, b.saturated)


@pytest.mark.parametrize("fidelity", FIDELITIES, ids=lambda f: f.value)
@pytest.mark.parametrize("name", PRRR_SCENES)
def test_prrr_compiled_equals_python_loop(name, fidelity):
    scene = dataclasses.replace(load_scene(name), duration=0.3)
    plant, st = _prrr_plant(scene, fidelity)
    ref_ctl, fast_ctl = NumpyController(st.cfg, st.gains), NumpyController(st.cfg, st.gains)
    ref = plant.run(ref_ctl, st, compiled=False)
    assert plant.loop_engine == "python"
    h_ref, u_ref, warn_ref = plant.health, plant.u.copy(), plant.warnings()
    fast = plant.run(fast_ctl, st)
    assert plant.loop_engine == "compiled", plant.loop_reason
    _assert_same_traces(ref, fast)
    assert plant.health == h_ref and plant.warnings() == warn_ref
    np.testing.assert_array_equal(plant.u, u_ref)  # the held command, as the Python loop leaves it
    # the controller ends in the Python loop's state (a caller may step it on)
    assert (fast_ctl._sp, fast_ctl._sv, fast_ctl._si, fast_ctl._tick) == (ref_ctl._sp, ref_ctl._sv, ref_ctl._si,
                                                                          ref_ctl._tick)
    np.testing.assert_array_equal(fast_ctl.last_force, ref_ctl.last_force)


@pytest.mark.parametrize("fidelity", FIDELITIES, ids=lambda f: f.value)
def test_prrr_simulate_status_and_health_equal(fidelity):
    scene = dataclasses.replace(load_scene("stiffness-25-links"), duration=0.3)
    ref = prrr_mj.simulate(PRRR, scene, fidelity=fidelity, compiled=False)
    fast = prrr_mj.simulate(PRRR, scene, fidelity=fidelity)
    assert (fast.loop_engine, ref.loop_engine) == ("compiled", "python")
    assert fast.status == ref.status and fast.message == ref.message and fast.health == ref.health
    assert fast.metrics()["closed_loop_engine"] == "compiled"
    assert ref.metrics()["closed_loop_engine"].startswith("python: compiled=False")
    _assert_same_traces(ref.traces, fast.traces)


def test_prrr_unstable_run_stops_at_the_same_tick():
    """The unstable wall of test_mujoco_plant (MuJoCo's BADQACC reset): same stop tick, same flag and warnings."""
    box = load_scene("virtual-box")
    scene = dataclasses.replace(box, environment=dataclasses.replace(box.environment, wall_stiffness=1000 * 28e3),
                                duration=0.2, effects=box.effects - {Effect.SATURATION})
    plant, st = _prrr_plant(scene, Fidelity.DRAFT)
    ref = plant.run(NumpyController(st.cfg, st.gains), st, compiled=False)
    bad_ref, warn_ref = plant.bad_qacc, plant.warnings()
    fast = plant.run(NumpyController(st.cfg, st.gains), st)
    assert plant.loop_engine == "compiled"
    assert ref.stop_tick[0] >= 0
    _assert_same_traces(ref, fast)
    assert plant.bad_qacc == bad_ref and plant.warnings() == warn_ref


def test_prrr_interpolated_controller_falls_back_with_the_reason():
    """Interpolation > 1 uses the generic numpy controller path: the Python loop runs and says why."""
    scene = dataclasses.replace(load_scene("stiffness-25"), duration=0.05)
    scene = dataclasses.replace(scene, controller=dataclasses.replace(scene.controller, interpolation=4))
    plant, st = _prrr_plant(scene, Fidelity.DRAFT)
    plant.run(NumpyController(st.cfg, st.gains), st)
    assert plant.loop_engine == "python" and "interpolation > 1" in plant.loop_reason


def test_unavailable_compiled_loop_falls_back_with_the_reason(monkeypatch):
    monkeypatch.setattr(mc, "availability", lambda: "numba not importable (test)")
    scene = dataclasses.replace(load_scene("stiffness-25"), duration=0.05)
    r = prrr_mj.simulate(PRRR, scene, fidelity=Fidelity.DRAFT)
    assert r.loop_engine == "python" and r.metrics()["closed_loop_engine"] == "python: numba not importable (test)"


def _master_runs(name, fidelity, duration):
    scene = dataclasses.replace(load_scene(name), duration=duration, sweep_factors=())
    ref = master_mj.simulate(MASTER, scene, fidelity=fidelity, compiled=False)
    fast = master_mj.simulate(MASTER, scene, fidelity=fidelity)
    return ref, fast


def _assert_same_master(ref, fast):
    assert fast.status == ref.status and fast.message == ref.message and fast.stable == ref.stable
    assert fast.violation == ref.violation and fast.warnings == ref.warnings
    for k in ("position", "velocity", "hand_force", "force_reference"):
        np.testing.assert_array_equal(getattr(fast.traces, k), getattr(ref.traces, k), err_msg=k)
    assert fast.traces.stop_tick[0] == ref.traces.stop_tick[0]
    assert {k: v for k, v in fast.measures.items()} == {k: v for k, v in ref.measures.items()}


@pytest.mark.parametrize("fidelity", FIDELITIES, ids=lambda f: f.value)
def test_master_wall_compiled_equals_python_loop(fidelity):
    ref, fast = _master_runs("master-wall", fidelity, 0.6)  # 0.6 s: the hand reaches the wall (8 mm at 1 Hz, wall 5 mm)
    assert (fast.loop_engine, ref.loop_engine) == ("compiled", "python"), fast.loop_reason
    assert fast.measures["wall_penetration_mm"] > 0.0  # the wall branch of the law ran
    _assert_same_master(ref, fast)


def test_master_raw_records_equal_with_delay_and_torque_limit():
    """MasterPlant.run directly, with a 3-tick delay line and a torque limit the wall reaches: every record equal."""
    scene = dataclasses.replace(load_scene("master-wall"), duration=0.6)
    from hapticopt.analysis.loop.scene import resolve

    res = resolve(scene)
    T = scene.controller.period
    plant = master_mj.MasterPlant(MASTER, scene, res, period=T, fidelity=Fidelity.DRAFT)
    kw = dict(ticks=600, frequency=1.0, quantize=True, delay_ticks=3)
    base = master_mj.controller_for(MASTER, scene, res, plant.x0, plant.q0, T)
    lim = 0.5 * float(np.abs(plant.run(base, **kw, compiled=False)["torque"]).max())  # the limit sits inside the run
    cfg = dataclasses.replace(base.cfg, torque_limit=lim, saturation=True)
    ctl, ctl_fast = MasterController(cfg), MasterController(cfg)
    ref = plant.run(ctl, **kw, compiled=False)
    fast = plant.run(ctl_fast, **kw)
    assert plant.loop_engine == "compiled"
    assert np.any(np.abs(ref["torque"]) == lim)  # saturation and delay exercised
    for k in ref:
        np.testing.assert_array_equal(fast[k], ref[k], err_msg=k)
    np.testing.assert_array_equal(ctl_fast._p_prev, ctl._p_prev)
    np.testing.assert_array_equal(ctl_fast._v, ctl._v)


def test_master_dynamics_compensation_falls_back_with_the_reason():
    """master-protocol-x compensates the links' dynamics (numpy mass model): not compiled, the Python loop runs and
    the result says why; the numbers are the Python loop's."""
    ref, fast = _master_runs("master-protocol-x", Fidelity.DRAFT, 0.05)
    assert fast.loop_engine == "python" and "dynamics compensation" in fast.loop_reason
    assert fast.metrics()["closed_loop_engine"].startswith("python: dynamics compensation")
    _assert_same_master(ref, fast)


def test_warm_up_loads_the_kernels_the_plants_use():
    """warm_up compiles/loads the same specialisations a run uses (one signature per kernel after both)."""
    assert mc.warm_up() is None
    k = mc.kernels()
    scene = dataclasses.replace(load_scene("stiffness-25"), duration=0.02)
    prrr_mj.simulate(PRRR, scene, fidelity=Fidelity.DRAFT)
    master_mj.simulate(MASTER, dataclasses.replace(load_scene("master-wall"), duration=0.02), fidelity=Fidelity.DRAFT)
    assert len(k.prrr_chunk.signatures) == 1 and len(k.master_chunk.signatures) == 1


def test_prrr_reset_restores_the_start_pose_exactly():
    """MujocoPlant.reset solves the IK once and restores its qpos afterwards: the same MjData state as a fresh plant."""
    scene = dataclasses.replace(load_scene("stiffness-25-links"), duration=0.05)
    plant, st = _prrr_plant(scene, Fidelity.DRAFT)
    first = {k: getattr(plant.data, k).copy() for k in ("qpos", "qvel", "qacc", "xpos", "efc_pos", "qfrc_applied")}
    plant.run(NumpyController(st.cfg, st.gains), st)
    plant.reset()
    for k, v in first.items():
        np.testing.assert_array_equal(getattr(plant.data, k), v, err_msg=k)
    np.testing.assert_array_equal(plant.model.qpos_spring, _prrr_plant(scene, Fidelity.DRAFT)[0].model.qpos_spring)


def test_master_unstable_run_stops_at_the_same_tick():
    """A wall 10⁴× master-wall's (10 kN/mm), no torque limit: MuJoCo's BADQACC reset stops both loops at one tick."""
    w = load_scene("master-wall")
    scene = dataclasses.replace(w, environment=dataclasses.replace(w.environment, wall_stiffness=1e7), duration=0.3,
                                effects=w.effects - {Effect.SATURATION})
    ref = master_mj.simulate(MASTER, scene, fidelity=Fidelity.DRAFT, compiled=False)
    fast = master_mj.simulate(MASTER, scene, fidelity=Fidelity.DRAFT)
    assert fast.loop_engine == "compiled" and ref.traces.stop_tick[0] >= 0 and not ref.stable
    assert any("BADQACC" in x for x in fast.warnings)
    _assert_same_master(ref, fast)
