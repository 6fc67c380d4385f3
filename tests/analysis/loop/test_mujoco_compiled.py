"""The compiled MuJoCo closed loops (analysis/loop/mujoco_compiled.py) against the Python loops they replace.

The reference is each plant's own Python loop (``run(..., compute=PYTHON)``): the compiled loop must give the
same records bit for bit (the requirement is ≤ 1e-12 relative; the law is mirrored operation by operation,
so equality is exact), the same stop tick, saturation flags, constraint health and status. Scenes: the five
3-PRRR scenes and the master scenes of docs/performance.md, draft and standard, shortened to 0.3 s. The master scenes
with dynamics compensation cannot be bit-identical (their reference differences M̂ numerically): they are held to the
reference's own rounding envelope, measured in the test (ENVELOPE_FACTOR below).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.compute import Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.loop import mujoco_compiled as mc
from hapticopt.analysis.loop.scene import Backend, Effect, load_scene, resolve
from hapticopt.analysis.prrr.loop import closed_loop
from hapticopt.analysis.prrr.loop import mujoco_plant as prrr_mj
from hapticopt.analysis.prrr.loop.firmware import ScalarController, controller
from hapticopt.analysis.prrr.loop.mujoco_model import Platform
from hapticopt.analysis.master import mujoco_plant as master_mj
from hapticopt.analysis.master.firmware import MasterController
from hapticopt.design.io import load_preset

PRRR = load_preset("prrr-paper")
MASTER = load_preset("master-paper")
PRRR_SCENES = ["stiffness-25", "free-space", "virtual-box", "free-space-x", "stiffness-25-links"]
FIDELITIES = [Fidelity.DRAFT, Fidelity.STANDARD]
PYTHON = Compute(backend="numpy")  # the plants' Python loops: the reference
TRACE_KEYS = ("position", "velocity", "hand_force", "actuator_force", "force_reference", "energy")


def test_compiled_loops_are_available_here():
    """numba, libmujoco and the mjData layout check out on this machine (else every run falls back)."""
    assert mc.availability() is None
    lay = mc.layout()
    assert lay.ne < lay.nefc < lay.time < lay.efc_pos  # info header, then the pointer fields


def _prrr_plant(scene, fidelity):
    ch = resolve(scene, force=Backend.MULTIBODY)
    st = closed_loop.setup(PRRR, dataclasses.replace(scene, effects=scene.effects - {Effect.LINK_DYNAMICS}),
                           fidelity=fidelity)
    plant = prrr_mj.MujocoPlant(PRRR, scene, prrr_mj.model_options(scene, ch, fidelity=fidelity,
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
    ref_ctl, fast_ctl = ScalarController(st.cfg, st.gains), ScalarController(st.cfg, st.gains)
    ref = plant.run(ref_ctl, st, compute=PYTHON)
    assert plant.loop_engine == "python"
    h_ref, u_ref, warn_ref = plant.health, plant.u.copy(), plant.warnings()
    fast = plant.run(fast_ctl, st)
    assert plant.loop_engine == "compiled", plant.loop_reason
    _assert_same_traces(ref, fast)
    assert plant.health == h_ref and plant.warnings() == warn_ref
    np.testing.assert_array_equal(plant.u, u_ref)  # the held command, as the Python loop leaves it
    # the controller ends in the Python loop's state (a caller may step it on)
    assert (fast_ctl.state, fast_ctl.tick) == (ref_ctl.state, ref_ctl.tick)


@pytest.mark.parametrize("fidelity", FIDELITIES, ids=lambda f: f.value)
def test_prrr_simulate_status_and_health_equal(fidelity):
    scene = dataclasses.replace(load_scene("stiffness-25-links"), duration=0.3)
    ref = prrr_mj.simulate(PRRR, scene, fidelity=fidelity, compute=PYTHON)
    fast = prrr_mj.simulate(PRRR, scene, fidelity=fidelity)
    assert (fast.loop_engine, ref.loop_engine) == ("compiled", "python")
    assert fast.status == ref.status and fast.message == ref.message and fast.health == ref.health
    assert fast.metrics()["closed_loop_engine"] == "compiled"
    assert ref.metrics()["closed_loop_engine"].startswith("python: compute backend numpy")
    _assert_same_traces(ref.traces, fast.traces)


def test_prrr_unstable_run_stops_at_the_same_tick():
    """The unstable wall of test_mujoco_plant (MuJoCo's BADQACC reset): same stop tick, same flag and warnings."""
    box = load_scene("virtual-box")
    scene = dataclasses.replace(box, environment=dataclasses.replace(box.environment, wall_stiffness=1000 * 28e3),
                                duration=0.2, effects=box.effects - {Effect.SATURATION})
    plant, st = _prrr_plant(scene, Fidelity.DRAFT)
    ref = plant.run(ScalarController(st.cfg, st.gains), st, compute=PYTHON)
    bad_ref, warn_ref = plant.bad_qacc, plant.warnings()
    fast = plant.run(ScalarController(st.cfg, st.gains), st)
    assert plant.loop_engine == "compiled"
    assert ref.stop_tick[0] >= 0
    _assert_same_traces(ref, fast)
    assert plant.bad_qacc == bad_ref and plant.warnings() == warn_ref


def test_prrr_interpolated_controller_falls_back_with_the_reason():
    """Interpolation > 1 is the jax law's (FirmwareController): the Python loop runs it and says why."""
    scene = dataclasses.replace(load_scene("stiffness-25"), duration=0.05)
    scene = dataclasses.replace(scene, controller=dataclasses.replace(scene.controller, interpolation=4))
    plant, st = _prrr_plant(scene, Fidelity.DRAFT)
    plant.run(controller(st.cfg, st.gains), st)
    assert plant.loop_engine == "python" and "FirmwareController has no compiled law" in plant.loop_reason


def test_unavailable_compiled_loop_falls_back_with_the_reason(monkeypatch):
    monkeypatch.setattr(mc, "availability", lambda: "numba not importable (test)")
    scene = dataclasses.replace(load_scene("stiffness-25"), duration=0.05)
    r = prrr_mj.simulate(PRRR, scene, fidelity=Fidelity.DRAFT)
    assert r.loop_engine == "python" and r.metrics()["closed_loop_engine"] == "python: numba not importable (test)"


def test_forced_numba_raises_where_the_compiled_loop_cannot_load(monkeypatch):
    monkeypatch.setattr(mc, "availability", lambda: "numba not importable (test)")
    scene = dataclasses.replace(load_scene("stiffness-25"), duration=0.05)
    with pytest.raises(RuntimeError, match=r"compute backend numba: numba not importable \(test\)"):
        prrr_mj.simulate(PRRR, scene, fidelity=Fidelity.DRAFT, compute=Compute(backend="numba"))


def _master_runs(name, fidelity, duration):
    scene = dataclasses.replace(load_scene(name), duration=duration, sweep_factors=())
    ref = master_mj.simulate(MASTER, scene, fidelity=fidelity, compute=PYTHON)
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
    lim = 0.5 * float(np.abs(plant.run(base, **kw, compute=PYTHON)["torque"]).max())  # the limit sits inside the run
    cfg = dataclasses.replace(base.cfg, torque_limit=lim, saturation=True)
    ctl, ctl_fast = MasterController(cfg), MasterController(cfg)
    ref = plant.run(ctl, **kw, compute=PYTHON)
    fast = plant.run(ctl_fast, **kw)
    assert plant.loop_engine == "compiled"
    assert np.any(np.abs(ref["torque"]) == lim)  # saturation and delay exercised
    for k in ref:
        np.testing.assert_array_equal(fast[k], ref[k], err_msg=k)
    np.testing.assert_array_equal(ctl_fast._p_prev, ctl._p_prev)
    np.testing.assert_array_equal(ctl_fast._v, ctl._v)


# ------------------------------------------------------------------ dynamics compensation (master-protocol-*, …)
#: The compensation scenes cannot be bit-identical: the reference (firmware.compensation_torque) takes Ĉ q̂̇ by central
#: differences of M̂ with h = 1e-6 rad (its rounding, ε|M̂|/h ≈ 1e-10 relative, is amplified 1e6×) over numpy einsums
#: (summation order numpy's); the compiled law sums the same vector in closed form (Lagrange's equations body by
#: body). The tolerance is the reference's own rounding sensitivity, measured here: the Python loop against itself
#: with q moved by one ulp inside compensation_torque. FACTOR: the compiled loop's distance to the reference over
#: that envelope measured 0.3–1.4 per trace (protocol-x/z and transparency at draft and standard, the short runs
#: below; 0.74–1.08 over the scenes' full 3 s); 4 leaves room for another run length / BLAS without admitting anything
#: beyond rounding (the envelope is 1e-15…1e-11 of each trace's range). The law itself is checked state by state:
#: against compensation_torque at large velocities (dropping the bodies' angular acceleration moved the torque by
#: 1.6e-2 N·m against an envelope of 3e-11 N·m) and against the exact (jax autodiff) dynamics on a general body set
#: (dropping the gyroscopic term's x row: 2.4e-3 N·m off); in the short, slow scene runs the velocity-product terms
#: are too small for the traces to tell such a change apart.
ENVELOPE_FACTOR = 4.0
COMP_KEYS = ("position", "velocity", "hand_force", "force_reference")


def _ulp_reference(monkeypatch):
    """compensation_torque with q moved by one ulp (the reference's rounding sensitivity)."""
    from hapticopt.analysis.master import firmware

    orig = firmware.compensation_torque

    def moved(model, weights, q, qd, qdd):
        return orig(model, weights, np.nextafter(np.asarray(q), np.inf), qd, qdd)

    monkeypatch.setattr(firmware, "compensation_torque", moved)
    return orig


def test_compiled_compensation_torque_within_the_references_rounding():
    """The kernel's M̂ q̈ + Ĉ q̇ against firmware.compensation_torque at random states: the distance is within
    ENVELOPE_FACTOR × the reference's own change under a one-ulp move of q (max over the states)."""
    from hapticopt.analysis.master import dynamics as md
    from hapticopt.analysis.master import firmware

    k = mc.kernels()
    model = md.model_of(MASTER)
    w = 1.0 - np.asarray(model.counterweight)
    args = (np.array([float(model.kin.upper_arm), float(model.kin.forearm), float(model.kin.driver_link),
                      float(model.kin.shoulder_height)]), np.argmax(np.asarray(model.frame), axis=1).astype(np.intp),
            w, np.asarray(model.mass, float), np.asarray(model.com, float), np.asarray(model.inertia, float),
            np.asarray(model.rotor_inertia, float))
    coef = k.mass_basis(*args)
    rng = np.random.default_rng(3)
    dist, env = 0.0, 0.0
    for _ in range(50):
        q, qd, qdd = rng.uniform(-1.5, 1.5, 3), rng.normal(0, 2, 3), rng.normal(0, 50, 3)
        ref = firmware.compensation_torque(model, w, q, qd, qdd)
        env = max(env, float(np.abs(firmware.compensation_torque(model, w, np.nextafter(q, np.inf), qd, qdd) - ref).max()))
        dist = max(dist, float(np.abs(k.compensation(q, qd, qdd, coef) - ref).max()))
    assert env > 0.0
    assert dist <= ENVELOPE_FACTOR * env, (dist, env)
    # the mass matrix alone (q̇ = 0) has no difference quotient: equal to ~1e-15 relative (summation order only)
    q, qdd = rng.uniform(-1.5, 1.5, 3), rng.normal(0, 50, 3)
    ref = firmware.compensation_torque(model, w, q, np.zeros(3), qdd)
    np.testing.assert_allclose(k.compensation(q, np.zeros(3), qdd, coef), ref, rtol=1e-13, atol=0.0)


def test_compiled_compensation_is_the_exact_dynamics_on_a_general_body_set():
    """The kernel's closed form against the jax reference dynamics (autodiff: M(q) and C(q, q̇)q̇ from the Christoffel
    symbols, exact to rounding) on master-paper's bodies with random CoMs (all three axes) and random full inertia
    tensors, so that every term (off-diagonal inertia, gyroscopic ω × Iω, CoM off the frame axes) counts. Both sides
    are analytic: they agree to rounding — measured ≤ 6e-16 relative on master-paper's own bodies, where the
    reference's central difference is 1.4e-10 (median) off; tolerance 1e-12, far below that difference."""
    from hapticopt.analysis.master import dynamics as md

    k = mc.kernels()
    rng = np.random.default_rng(11)
    base = md.model_of(MASTER)
    nb = len(np.asarray(base.mass))
    A = rng.normal(0.0, 1e-2, (nb, 3, 3))
    inertia = np.einsum("bij,bkj->bik", A, A) + 1e-5 * np.eye(3)  # symmetric positive definite, full
    model = base._replace(com=rng.normal(0.0, 0.05, (nb, 3)), inertia=inertia, mass=rng.uniform(0.01, 0.5, nb))
    w = np.ones(nb)
    args = (np.array([float(model.kin.upper_arm), float(model.kin.forearm), float(model.kin.driver_link),
                      float(model.kin.shoulder_height)]), np.argmax(np.asarray(model.frame), axis=1).astype(np.intp),
            w, np.asarray(model.mass, float), np.asarray(model.com, float), np.asarray(model.inertia, float),
            np.asarray(model.rotor_inertia, float))
    Q, QD, QDD = rng.uniform(-1.2, 1.2, (20, 3)), rng.normal(0, 2, (20, 3)), rng.normal(0, 50, (20, 3))
    exact = np.einsum("nij,nj->ni", np.asarray(md.mass_matrix(model, Q)), QDD) + np.asarray(md.coriolis(model, Q, QD))
    coef = k.mass_basis(*args)
    got = np.array([k.compensation(q, qd, qdd, coef) for q, qd, qdd in zip(Q, QD, QDD)])
    np.testing.assert_allclose(got, exact, rtol=0.0, atol=1e-12 * float(np.abs(exact).max()))


def _body_args(model, w):
    """A compensation model (hapticopt.analysis.master.dynamics.MassModel) as the kernels' plain arrays."""
    return (np.array([float(model.kin.upper_arm), float(model.kin.forearm), float(model.kin.driver_link),
                      float(model.kin.shoulder_height)]), np.argmax(np.asarray(model.frame), axis=1).astype(np.intp),
            np.asarray(w, float), np.asarray(model.mass, float), np.asarray(model.com, float),
            np.asarray(model.inertia, float), np.asarray(model.rotor_inertia, float))


def _general_bodies(seed):
    """master-paper's bodies with random CoMs and full inertia tensors, all weighted (every basis term counts)."""
    from hapticopt.analysis.master import dynamics as md

    rng = np.random.default_rng(seed)
    base = md.model_of(MASTER)
    nb = len(np.asarray(base.mass))
    A = rng.normal(0.0, 1e-2, (nb, 3, 3))
    model = base._replace(com=rng.normal(0.0, 0.05, (nb, 3)), inertia=np.einsum("bij,bkj->bik", A, A) + 1e-5 * np.eye(3),
                          mass=rng.uniform(0.01, 0.5, nb))
    return model, np.ones(nb)


def test_mass_basis_holds_the_mass_matrix_to_rounding_and_tells_a_miss():
    """M̂ identified in the kernel's trig basis (8 × 8 grid) against the body-by-body M̂ at 16 poses off the grid (θ1 ≠ 0
    too): relative residual at rounding (measured 6e-16 on master-paper, 5e-16 on general bodies) — bound 1e-14,
    a structural miss is O(1): zero coefficients give 1, a single coefficient off by 1e-9 of the largest gives ≥ 1e-10."""
    from hapticopt.analysis.master import dynamics as md

    k = mc.kernels()
    base = md.model_of(MASTER)
    for model, w in ((base, 1.0 - np.asarray(base.counterweight)), _general_bodies(5), _general_bodies(6)):
        args = _body_args(model, w)
        coef = k.mass_basis(*args)
        assert coef.shape == (k.N_BASIS, 6)
        assert k.mass_basis_residual(coef, *args) <= 1e-14
        assert k.mass_basis_residual(np.zeros_like(coef), *args) == 1.0
        bad = coef.copy()
        bad[9, 0] += 1e-9 * np.abs(coef).max()  # cos θ2 cos θ3 in M11: a term the grid would resolve
        assert k.mass_basis_residual(bad, *args) >= 1e-10
    assert master_mj.MASS_BASIS_RESIDUAL >= 1e-12  # the plant's bound: decades above the 1e-14 asserted here


def compensation_bodies(k, q, qd, qdd, *args) -> np.ndarray:
    """The kernels' body-by-body torque (``k._compensation``) at one state, with its own scratch."""
    out = np.empty(3)
    k._compensation(math.cos(q[0]), math.sin(q[0]), math.cos(q[1]), math.sin(q[1]), math.cos(q[2]), math.sin(q[2]),
                    qd, qdd, *args, k.comp_scratch(), out)
    return out


def test_compiled_compensation_basis_equals_the_body_by_body_form():
    """The per-tick torque from M̂'s basis coefficients against the body-by-body closed form it was identified from,
    at random states with large velocities (the Ĉ q̂̇ terms count): the same torque to rounding (measured ≤ 3e-15 of
    the torque's largest component; tolerance 1e-13, far under the reference's 1e-11 rounding envelope)."""
    from hapticopt.analysis.master import dynamics as md

    k = mc.kernels()
    base = md.model_of(MASTER)
    rng = np.random.default_rng(7)
    for model, w in ((base, 1.0 - np.asarray(base.counterweight)), _general_bodies(8)):
        args = _body_args(model, w)
        coef = k.mass_basis(*args)
        for _ in range(40):
            q, qd, qdd = rng.uniform(-3.0, 3.0, 3), rng.normal(0, 5, 3), rng.normal(0, 50, 3)
            want = compensation_bodies(k, q, qd, qdd, *args)
            got = k.compensation(q, qd, qdd, coef)
            assert float(np.abs(got - want).max()) <= 1e-13 * float(np.abs(want).max()), (q, qd, qdd)
        # the velocity-product part alone (q̂̈ = 0), where Ĉ q̂̇ is all there is
        q, qd = rng.uniform(-3.0, 3.0, 3), rng.normal(0, 5, 3)
        want = compensation_bodies(k, q, qd, np.zeros(3), *args)
        np.testing.assert_allclose(k.compensation(q, qd, np.zeros(3), coef), want, rtol=0.0,
                                   atol=1e-13 * float(np.abs(want).max()))


def test_master_compensation_outside_the_basis_falls_back_with_the_reason(monkeypatch):
    """When M̂'s identified coefficients do not reproduce M̂ (residual over MASS_BASIS_RESIDUAL: here the identification
    made to return zeros), the compensation has no compiled law: the Python loop runs and says why. A plant identifies
    a compensation model's coefficients once (later runs with the same model reuse them)."""
    scene = dataclasses.replace(load_scene("master-protocol-x"), duration=0.01)
    from hapticopt.analysis.loop.scene import resolve

    res = resolve(scene)
    T = scene.controller.period
    plant = master_mj.MasterPlant(MASTER, scene, res, period=T, fidelity=Fidelity.DRAFT)
    k = mc.kernels()
    plant.run(master_mj.controller_for(MASTER, scene, res, plant.x0, plant.q0, T), ticks=5, frequency=1.0,
              quantize=False)
    assert plant.loop_engine == "compiled"
    monkeypatch.setattr(k, "mass_basis", lambda *a: np.zeros((k.N_BASIS, 6)))
    plant.run(master_mj.controller_for(MASTER, scene, res, plant.x0, plant.q0, T), ticks=5, frequency=1.0,
              quantize=False)
    assert plant.loop_engine == "compiled"  # the same model: its coefficients were identified once, on the first run
    fresh = master_mj.MasterPlant(MASTER, scene, res, period=T, fidelity=Fidelity.DRAFT)
    fresh.run(master_mj.controller_for(MASTER, scene, res, fresh.x0, fresh.q0, T), ticks=5, frequency=1.0,
              quantize=False)
    assert fresh.loop_engine == "python" and "trig basis" in fresh.loop_reason


@pytest.mark.parametrize("name,duration", [("master-protocol-x", 0.15), ("master-protocol-z", 0.15),
                                           ("master-transparency", 0.06)])
def test_master_compensation_compiled_within_the_references_rounding(name, duration, monkeypatch):
    """The compensation scenes at draft (shortened; the sweep's first frequency as a plain spring run): the compiled
    loop runs them; every trace within ENVELOPE_FACTOR × the reference's own one-ulp envelope; the same stop tick,
    saturation, status, message, stability, warnings; the closure residual (health) within the position envelope."""
    ref, fast = _master_runs(name, Fidelity.DRAFT, duration)
    assert (fast.loop_engine, ref.loop_engine) == ("compiled", "python"), fast.loop_reason
    _ulp_reference(monkeypatch)
    scene = dataclasses.replace(load_scene(name), duration=duration, sweep_factors=())
    moved = master_mj.simulate(MASTER, scene, fidelity=Fidelity.DRAFT, compute=PYTHON)
    assert fast.status == ref.status and fast.message == ref.message and fast.stable == ref.stable
    assert fast.warnings == ref.warnings and fast.health_ok == ref.health_ok
    assert fast.traces.stop_tick[0] == ref.traces.stop_tick[0] == moved.traces.stop_tick[0]
    assert fast.measures["torque_saturated_fraction"] == ref.measures["torque_saturated_fraction"]
    for k in COMP_KEYS:
        a, b, c = getattr(ref.traces, k), getattr(fast.traces, k), getattr(moved.traces, k)
        env = float(np.abs(c - a).max())
        assert env > 0.0, k  # the reference is sensitive to its rounding here (else no tolerance to derive)
        assert float(np.abs(b - a).max()) <= ENVELOPE_FACTOR * env, (k, float(np.abs(b - a).max()), env)
    env_p = float(np.abs(moved.traces.position - ref.traces.position).max())
    assert abs(fast.violation - ref.violation) <= ENVELOPE_FACTOR * env_p


def test_master_compensation_without_a_one_hot_model_falls_back_with_the_reason():
    """A compensation model whose bodies are not each on one link frame has no compiled law: the Python loop runs."""
    scene = dataclasses.replace(load_scene("master-protocol-x"), duration=0.01)
    from hapticopt.analysis.loop.scene import resolve

    res = resolve(scene)
    T = scene.controller.period
    plant = master_mj.MasterPlant(MASTER, scene, res, period=T, fidelity=Fidelity.DRAFT)
    base = master_mj.controller_for(MASTER, scene, res, plant.x0, plant.q0, T)
    cm = base.cfg.compensation_model
    blended = cm._replace(frame=0.5 * np.asarray(cm.frame) + 0.5 * np.roll(np.asarray(cm.frame), 1, axis=1))
    ctl = MasterController(dataclasses.replace(base.cfg, compensation_model=blended))
    plant.run(ctl, ticks=5, frequency=1.0, quantize=False)
    assert plant.loop_engine == "python" and "one link frame" in plant.loop_reason


def test_master_compensation_controller_state_continues(monkeypatch):
    """After a compiled run the controller holds the Python loop's filter state (samples, q_prev, q̂̇, q̂̈, p_prev, v, F):
    the same samples count; the states within what ENVELOPE_FACTOR × the reference's one-ulp envelope of the handle
    position (max over the run) allows, carried through the firmware's arithmetic: p_prev δp; the joint angles
    δp / min(L5, L4) (an arm turning by δq moves the handle by ≥ min(L5, L4)·δq); the no-filter differences v 2δp/T,
    q̂̇ 2δq/T, q̂̈ 4δq/T²; F = −K(p − p_r) − B v: K δp + B δv. (A single end state's own envelope is a few ulps or 0:
    too noisy to carry a tolerance.)"""
    scene = dataclasses.replace(load_scene("master-protocol-x"), duration=0.15)
    from hapticopt.analysis.loop.scene import resolve

    res = resolve(scene)
    T = scene.controller.period
    plant = master_mj.MasterPlant(MASTER, scene, res, period=T, fidelity=Fidelity.DRAFT)
    a, b, c = (master_mj.controller_for(MASTER, scene, res, plant.x0, plant.q0, T) for _ in range(3))
    cfg = a.cfg
    assert cfg.velocity_alpha == 0.0 and cfg.env.value == "spring"
    kw = dict(ticks=600, frequency=1.0, quantize=False)
    ra = plant.run(a, **kw, compute=PYTHON)
    plant.run(b, **kw)
    assert plant.loop_engine == "compiled"
    _ulp_reference(monkeypatch)
    rc = plant.run(c, **kw, compute=PYTHON)
    assert a._samples == b._samples == c._samples == 600
    dp = ENVELOPE_FACTOR * float(np.abs(rc["position"] - ra["position"]).max())
    assert dp > 0.0
    dq = dp / min(cfg.upper_arm, cfg.forearm)
    dv = 2.0 * dp / T
    tol = {"_p_prev": dp, "_v": dv, "last_force": max(cfg.stiffness) * dp + max(cfg.damping) * dv,
           "_q_prev": dq, "_qd": 2.0 * dq / T, "_qdd": 4.0 * dq / T**2}
    for k, t in tol.items():
        assert float(np.abs(getattr(b, k) - getattr(a, k)).max()) <= t, k


def test_warm_up_loads_the_kernels_the_plants_use():
    """warm_up compiles/loads the same specialisations a run uses (one signature per kernel after both devices' runs,
    a compensation scene included)."""
    assert prrr_mj.warm_up() is None
    k = mc.kernels()
    from hapticopt.analysis.prrr.loop._mujoco_kernel import prrr_chunk  # loaded by warm_up
    scene = dataclasses.replace(load_scene("stiffness-25"), duration=0.02)
    prrr_mj.simulate(PRRR, scene, fidelity=Fidelity.DRAFT)
    master_mj.simulate(MASTER, dataclasses.replace(load_scene("master-wall"), duration=0.02), fidelity=Fidelity.DRAFT)
    master_mj.simulate(MASTER, dataclasses.replace(load_scene("master-protocol-x"), duration=0.01),
                       fidelity=Fidelity.DRAFT)  # the compensation's basis identification too
    assert len(prrr_chunk.signatures) == 1 and len(k.master_chunk.signatures) == 1
    assert len(k.mass_basis.signatures) == 1 and len(k.mass_basis_residual.signatures) == 1


def test_prrr_reset_restores_the_start_pose_exactly():
    """MujocoPlant.reset solves the IK once and restores its qpos afterwards: the same MjData state as a fresh plant."""
    scene = dataclasses.replace(load_scene("stiffness-25-links"), duration=0.05)
    plant, st = _prrr_plant(scene, Fidelity.DRAFT)
    first = {k: getattr(plant.data, k).copy() for k in ("qpos", "qvel", "qacc", "xpos", "efc_pos", "qfrc_applied")}
    plant.run(ScalarController(st.cfg, st.gains), st)
    plant.reset()
    for k, v in first.items():
        np.testing.assert_array_equal(getattr(plant.data, k), v, err_msg=k)
    np.testing.assert_array_equal(plant.model.qpos_spring, _prrr_plant(scene, Fidelity.DRAFT)[0].model.qpos_spring)


def test_master_unstable_run_stops_at_the_same_tick():
    """A wall 10⁴× master-wall's (10 kN/mm), no torque limit: MuJoCo's BADQACC reset stops both loops at one tick."""
    w = load_scene("master-wall")
    scene = dataclasses.replace(w, environment=dataclasses.replace(w.environment, wall_stiffness=1e7), duration=0.3,
                                effects=w.effects - {Effect.SATURATION})
    ref = master_mj.simulate(MASTER, scene, fidelity=Fidelity.DRAFT, compute=PYTHON)
    fast = master_mj.simulate(MASTER, scene, fidelity=Fidelity.DRAFT)
    assert fast.loop_engine == "compiled" and ref.traces.stop_tick[0] >= 0 and not ref.stable
    assert any("BADQACC" in x for x in fast.warnings)
    _assert_same_master(ref, fast)
