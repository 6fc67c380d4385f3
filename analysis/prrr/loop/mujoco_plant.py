"""The multibody (MuJoCo) plant of the 3-PRRR in the closed loop.

The model of :mod:`hapticopt.analysis.prrr.loop.mujoco_model` against the
firmware controller (the law of ``hapticopt.analysis.prrr.loop.firmware_law`` on floats, or the jax step of
``hapticopt.analysis.prrr.loop.firmware`` with interpolation) at its period T; its commands are held (zero-order hold, or L samples per period with the seed 000 interpolation) over ``T / timestep``
MuJoCo substeps; the loop reads the plant's sensors and quantises them exactly as for the
lumped plant. The operator hand is a body (mass m_h on springs k_h and dampers b_h to the
reference motion, seed 000 eq 1) tied to the handle by a ``<connect>``; its reference is
updated once per period at the period's midpoint (second-order accurate).

Every run reports constraint health (worst closed-chain violation, platform rotation,
end-effector vs forward-kinematics closure) and MuJoCo's warnings; a run that leaves the
tolerance (:data:`VIOLATION_TOL`, :data:`ROTATION_TOL`) or raised a warning is flagged in its
status and message, never silently reported. A ``BADQACC`` warning (MuJoCo resets the state
on it, its clock goes back) stops the run as unstable.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.compute import DEFAULT, Backend as ComputeBackend, Compute
from hapticopt.analysis.prrr.loop.firmware import ScalarController, controller as firmware_controller
from hapticopt.analysis.loop import mujoco_compiled as mc
from hapticopt.analysis.loop.mujoco_solver import SOLVER_BY_FIDELITY, Health, SolverSettings
from hapticopt.analysis.loop.operator import Operator
from hapticopt.analysis.prrr.loop.mujoco_model import LinkMasses, ModelOptions, Platform, PrrrMj, build, set_pose
from hapticopt.analysis.loop.scene import Backend, Effect, FrictionLocation, Resolution, Scene, resolve
from hapticopt.analysis.status import Status
from hapticopt.design.errors import InvalidInput
from hapticopt.design.prrr.params import PrrrDesign
from hapticopt.analysis.prrr.loop import closed_loop
from hapticopt.analysis.prrr.loop.closed_loop import Traces
from hapticopt.analysis.loop.scene import StabilityCriterion

#: closed-chain tolerances of issue 8 (constraint violation [m], platform rotation [rad])
VIOLATION_TOL = 1e-5
ROTATION_TOL = 1e-4

#: ticks between the vectorised health/instability checks of the fast loop (every tick is checked)
CHECK_EVERY = 100


def model_options(scene: Scene, resolution: Resolution, *, fidelity: Fidelity = Fidelity.STANDARD,
                  platform: Platform = Platform.FREE, link_masses: LinkMasses | None = None) -> ModelOptions:
    """The MuJoCo model a scene's resolved effects call for."""
    fx = resolution.effects
    if scene.output_locked:
        raise InvalidInput(f"scene {scene.name}: simulation.output_locked tests the SEA force loop alone; "
                           "it runs on the lumped plant (no linkage moves)")
    op = scene.operator
    hand = (Operator(mass=op.mass, damping=op.damping, stiffness=op.stiffness)
            if Effect.OPERATOR in fx else None)
    if link_masses is None:
        link_masses = LinkMasses.REAL if Effect.LINK_DYNAMICS in fx else LinkMasses.LUMPED
    return ModelOptions(
        link_masses=link_masses, platform=platform,
        sea_compliance=Effect.SEA_COMPLIANCE in fx, motor_dynamics=Effect.MOTOR_DYNAMICS in fx,
        viscous_friction=Effect.VISCOUS_FRICTION in fx,
        coulomb_friction=Effect.COULOMB_FRICTION in fx and scene.friction_location != FrictionLocation.R_JOINTS,
        r_joint_friction=Effect.COULOMB_FRICTION in fx and scene.friction_location != FrictionLocation.SLIDERS,
        gravity=Effect.GRAVITY in fx, hand=hand, solver=SOLVER_BY_FIDELITY[fidelity],
    )


class MujocoPlant:
    """The MuJoCo 3-PRRR in the firmware's closed loop (:meth:`run`). Not thread-safe (owns one MjData)."""

    backend = "multibody"

    def __init__(self, design: PrrrDesign, scene: Scene, options: ModelOptions, *, period: float,
                 interpolation: int = 1) -> None:
        import mujoco

        self._mujoco = mujoco
        self.design, self.scene, self.options = design, scene, options
        self.mj: PrrrMj = build(design, options)
        self.model = self.mj.model
        self.data = mujoco.MjData(self.model)
        dt = options.solver.timestep
        n = max(1, int(round(period / dt)))
        L = max(1, interpolation)
        self.substeps = L * math.ceil(n / L)
        self.model.opt.timestep = period / self.substeps  # an exact multiple of the period
        self.period = period
        self._energy = False
        self.per_sample = self.substeps // L
        a = design.actuator
        self.rigid = options.motor_dynamics and not options.sea_compliance
        self.ideal = not options.motor_dynamics
        self.gain = 1.0 if self.ideal else a.efficiency
        self.spring = a.spring
        self.J = self.mj.jacobian
        self.JinvT = np.linalg.inv(self.J).T
        m = self.model
        self._eq_rows = 3 * m.neq
        self._free = options.platform is Platform.FREE
        self._J = np.asarray(self.mj.jacobian)
        self._ee_pos = self.mj.ee_qpos[:3]
        ee_dof = m.jnt_dofadr[m.body_jntadr[self.mj.ee_body]]
        self._ee_dof = np.arange(ee_dof, ee_dof + 3)
        self._slider_dof = np.asarray(self.mj.actuator_joint_dof)
        mo = scene.motion
        self._amp = np.asarray(mo.amplitude, dtype=float)
        self._offset = np.asarray(mo.offset, dtype=float)
        self._phase = np.asarray(mo.phase, dtype=float)
        self._w = 2.0 * math.pi * mo.frequency
        self._hand = options.hand
        if self._hand is not None:
            self._hand_spring_adr = np.asarray(self.mj.hand_qpos)  # qpos_spring shares qpos layout
        self.loop_engine, self.loop_reason = "python", "run() not called yet"
        self._pose0: np.ndarray | None = None  # qpos set_pose gives at the scene's start (cached by reset)
        self.reset()

    # ----------------------------------------------------------------------------- interface
    def reset(self) -> None:
        mj, d = self._mujoco, self.data
        mj.mj_resetData(self.model, d)
        p0 = np.asarray(self.scene.initial_offset, dtype=float)
        if self._pose0 is None:  # the IK (jax) once per plant; later resets restore what set_pose wrote
            set_pose(self.mj, d, p0)
            self._pose0 = d.qpos.copy()
        else:
            d.qpos[:] = self._pose0
            d.qvel[:] = 0.0
            mj.mj_forward(self.model, d)
        self.t = 0.0
        self.u = np.zeros(3)
        self._worst = [0.0, 0.0, 0.0]  # violation [m], rotation [rad], closure [m]
        self.bad_qacc = False
        if self._hand is not None:
            self._set_reference(0.0)
            d.qpos[self.mj.hand_qpos] = p0
        mj.mj_forward(self.model, d)

    # ----------------------------------------------------------------------------- internals
    def enable_energy(self) -> None:
        """Let MuJoCo compute kinetic energy (observation ``energy``); costs ≈ one mass-matrix product."""
        self.model.opt.enableflags |= self._mujoco.mjtEnableBit.mjENBL_ENERGY
        self._energy = True

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Hand reference x_r(t) and its rate [m, m/s]."""
        arg = self._w * t + self._phase
        return self._offset + self._amp * np.sin(arg), self._amp * self._w * np.cos(arg)

    def _set_reference(self, t: float) -> None:
        ref, dref = self.reference(t)
        self.model.qpos_spring[self._hand_spring_adr] = ref
        self.data.qfrc_applied[self.mj.hand_dof] = self._hand.damping * dref

    # ----------------------------------------------------------------------------- fast loop
    def run(self, controller: Any, st: Any, *, check_every: int = CHECK_EVERY, compute: Compute = DEFAULT) -> Any:
        """The firmware's closed loop on this plant, fused around ``mj_step``; raw traces for
        :func:`hapticopt.analysis.prrr.loop.closed_loop.metrics_from_traces`.

        Sensors, quantisation, controller calls, delay line, hand reference and stop rule as in a plain
        tick-by-tick loop; per tick only raw state is copied into preallocated arrays (qpos, qvel, qacc, kinetic
        energy, equality residuals ``efc_pos``, platform quaternion, body positions, MuJoCo's
        clock); observables, energy, constraint health and the instability checks are computed
        vectorised every ``check_every`` ticks over the whole window (every tick is checked, none is
        skipped: the first bad tick in the window is found and the traces stop there exactly as in
        the reference loop; the plant may have run up to ``check_every − 1`` ticks beyond, which
        nothing reads). Tested equal to a plain tick-by-tick reference (``tests/analysis/prrr/loop/test_mujoco_plant.py``).

        ``compute``: with a :class:`ScalarController` the ticks run in the compiled loop
        (:mod:`hapticopt.analysis.prrr.loop._mujoco_kernel`, the same law compiled: bit-identical records) unless
        ``compute`` says numpy or numba cannot load here (then in Python; with backend numba that raises);
        another controller (the jax law, interpolation > 1) runs in Python. :attr:`loop_engine` /
        :attr:`loop_reason` say which ran and why.
        """

        mj, m, d = self._mujoco, self.model, self.data
        if not self._energy:
            self.enable_energy()
        step = mj.mj_step
        N = st.ticks
        res = float(st.gains.resolution)
        inv_res = 1.0 / res
        quantize = st.quantize
        self.reset()
        qpos, qvel, qacc, ctrl = d.qpos, d.qvel, d.qacc, d.ctrl
        sl_idx = self.mj.slider_qpos
        mo_idx = self.mj.motor_qpos
        sl0 = int(sl_idx[0]) if np.all(np.diff(sl_idx) == 1) else None
        mo0 = int(mo_idx[0]) if mo_idx is not None and np.all(np.diff(mo_idx) == 1) else None

        # both encoders elementwise (no BLAS product: its summation order / FMA is the library's, and the
        # compiled loop must reproduce the counts bit for bit): slider/res, (motor − slider)/res
        sl_sel = slice(sl0, sl0 + 3) if sl0 is not None else sl_idx
        mo_sel = (slice(mo0, mo0 + 3) if mo0 is not None else mo_idx) if mo_idx is not None else None
        rnd = np.rint  # what np.round does at 0 decimals, without its wrapper

        def counts() -> tuple[np.ndarray, np.ndarray]:
            sl = qpos[sl_sel]
            a = sl * inv_res
            if self.ideal:  # the spring carries exactly the commanded force (no force loop reads it)
                b = (self.u / self.spring) * inv_res
            elif mo_sel is None:
                b = np.zeros(3)
            else:
                b = (qpos[mo_sel] - sl) * inv_res
            if quantize:
                a, b = rnd(a), rnd(b)
            return a, b

        sc, _ = counts()
        controller.reset(sc)
        kern = self._kernels(controller, compute, N)
        L = st.cfg.interpolation
        delay: list[np.ndarray] = [np.zeros((L, 3))] * st.delay_ticks
        nq, nv = m.nq, m.nv
        Qp, Qv, Qa = np.zeros((N, nq)), np.zeros((N, nv)), np.zeros((N, nv))
        KE = np.zeros(N)
        clock = np.zeros(N)
        CMD = np.zeros((N, L, 3))  # command samples applied (after the delay line)
        Fref = np.zeros((N, 3))
        n_eq = self._eq_rows
        EF = np.zeros((N, n_eq))
        hand = self._hand
        per = self.per_sample
        h = per * m.opt.timestep
        w, amp, off, ph = self._w, self._amp, self._offset, self._phase
        if hand is not None:
            spr_adr, hd = self._hand_spring_adr, self.mj.hand_dof
            if np.all(np.diff(spr_adr) == 1) and np.all(np.diff(hd) == 1):  # slices write faster
                spr_adr, hd = slice(int(spr_adr[0]), int(spr_adr[0]) + 3), slice(int(hd[0]), int(hd[0]) + 3)
            qs = m.qpos_spring
            qfa = d.qfrc_applied
            # reference at every sample midpoint: tick k, sample j → t = k·T + (j + ½)·h
            tm = (np.arange(N)[:, None] * (L * h) + (np.arange(L)[None, :] + 0.5) * h)[..., None]
            arg = w * tm + ph
            REF = off + amp * np.sin(arg)
            DREF = hand.damping * amp * w * np.cos(arg)
        gain = self.gain
        explode = (1e6 if st.scene.stability == StabilityCriterion.DECAY else 1e3) * st.energy_scale
        K = np.asarray(st.gains.stiffness, dtype=float)
        stop = -1
        start = 0
        ok_eq = n_eq > 0
        k = 0
        mul = np.multiply
        energy_buf = d.energy  # a view on MjData's buffer, updated in place by mj_step
        if kern is not None:
            nat = self._native_args(controller, st, N, REF if hand is not None else None,
                                    DREF if hand is not None else None, Qp, Qv, Qa, KE, clock, CMD, Fref, EF,
                                    K, explode, check_every)
        while k < N:
            end = min(N, start + check_every)
            if kern is not None:  # runs windows on until one holds a possibly bad tick (exact check below) or N
                end = kern(*nat[0], start, N, per, *nat[1])
                if end < 0:  # no tick was possibly bad: none is (the prefilter is conservative)
                    end = N
                    break
                start = ((end - 1) // check_every) * check_every  # that window
            for k in range(start, end) if kern is None else ():
                sc, dc = counts()
                cmd = controller.step(sc.tolist(), dc.tolist())
                if delay:
                    delay.append(cmd)
                    cmd = delay.pop(0)
                for j in range(L):
                    row = cmd[j]
                    mul(row, gain, out=ctrl)
                    if hand is not None:
                        qs[spr_adr] = REF[k, j]
                        qfa[hd] = DREF[k, j]
                    step(m, d, per)
                self.u = row
                Qp[k] = qpos
                Qv[k] = qvel
                Qa[k] = qacc
                KE[k] = energy_buf[1]
                clock[k] = d.time
                CMD[k] = cmd
                Fref[k] = controller.last_force
                if ok_eq:
                    efc = d.efc_pos
                    if efc.shape[0] >= n_eq:
                        EF[k] = efc[:n_eq]
            bad = self._window_bad(st, Qp, Qv, KE, clock, start, end, K, explode)
            if bad >= 0:
                stop = bad
                break
            start = end
            k = end
        if kern is not None:
            self._native_done(controller, nat, CMD, end)
        self.t = (N if stop < 0 else stop + 1) * L * h
        last = N if stop < 0 else stop + 1  # health over every tick run up to and including the stop
        self._health_from(EF[:last], Qp[:last])
        if stop >= 0 and clock[stop] < (stop + 0.5) * L * h:
            self.bad_qacc = True
        obs = self._observables(Qp, Qv, Qa, KE, CMD[:, -1], K)
        cmd_max = np.abs(CMD).max(axis=(1, 2))
        sat = (st.cfg.saturation & (cmd_max >= float(st.gains.motor_limit) * (1 - 1e-12)))[:, None]
        energy = obs.pop("energy")[:, None]
        rec = {k2: v[:, None, :] for k2, v in obs.items()}
        rec["force_reference"] = Fref[:, None, :]
        if stop >= 0:
            for arr in (*rec.values(), energy, sat):
                arr[stop:] = arr[stop - 1] if stop > 0 else 0
        return Traces(period=st.period, energy=energy, saturated=sat, stop_tick=np.array([stop]), **rec)

    def _kernels(self, controller: Any, compute: Compute, ticks: int) -> Any:
        """The compiled tick loop when ``compute`` and ``controller`` allow it (else None); records the engine and
        why."""
        if not isinstance(controller, ScalarController):
            why = f"controller {type(controller).__name__} has no compiled law (the scalar law of interpolation 1 has)"
        elif not compute.use_numba(ticks, 1):
            why = f"compute backend {compute.backend.value}: the Python loop"
        else:
            why = mc.availability()
            if why is not None and compute.backend is ComputeBackend.NUMBA:
                raise RuntimeError(f"compute backend numba: {why}")
        self.loop_engine = "python" if why else "compiled"
        self.loop_reason = why or "compiled loop (numba): firmware law and mj_step in one native loop"
        if why:
            return None
        from hapticopt.analysis.prrr.loop import _mujoco_kernel  # numba: loaded once availability() says it can

        return _mujoco_kernel.prrr_chunk

    def _native_args(self, controller, st, N, REF, DREF, Qp, Qv, Qa, KE, clock, CMD, Fref, EF, K, explode, check_every):
        """Arguments of :func:`hapticopt.analysis.prrr.loop._mujoco_kernel.prrr_chunk`: (before start/end/nstep, after)."""
        m, d = self.model, self.data
        lay = mc.layout()
        off = np.array([lay.time, lay.nefc, lay.efc_pos], dtype=np.int64)
        ip = lambda x: np.ascontiguousarray(x, dtype=np.intp)  # noqa: E731
        sl_idx = ip(self.mj.slider_qpos)
        has_motor = self.mj.motor_qpos is not None and not self.ideal
        mo_idx = ip(self.mj.motor_qpos) if has_motor else sl_idx
        if self._hand is not None:
            spr, hd = ip(self._hand_spring_adr), ip(self.mj.hand_dof)
            REF, DREF = np.ascontiguousarray(REF[:, 0, :]), np.ascontiguousarray(DREF[:, 0, :])
        else:
            spr = hd = np.zeros(3, dtype=np.intp)
            REF = DREF = np.zeros((1, 3))
        law = [np.array(a, dtype=np.int64 if i == 1 else np.float64) for i, a in enumerate(controller.args)]
        lpar = np.array([1.0 / float(st.gains.resolution), self.gain])
        lflg = np.array([st.quantize, has_motor, self._hand is not None, self._eq_rows, st.delay_ticks], dtype=np.int64)
        state = np.array(controller.state)
        ist = np.array([controller.tick, 0], dtype=np.int64)
        dbuf = np.zeros((max(1, st.delay_ticks), 3))
        # the window check's prefilter (_window_bad's quantities): end-effector, spring deflection, its stiffness
        ee = ip(self._ee_pos)
        mo_chk = self.mj.motor_qpos is not None
        chk_f = np.array([explode, self.spring, self.period])
        chk_i = np.array([check_every, mo_chk], dtype=np.int64)
        mo_e = ip(self.mj.motor_qpos) if mo_chk else sl_idx
        pre = (m._address, d._address, off)
        post = (d.qpos, d.qvel, d.qacc, d.ctrl, d.energy, m.qpos_spring, d.qfrc_applied, sl_idx, mo_idx, spr, hd,
                REF, DREF, *law, lpar, lflg, state, ist, dbuf, Qp, Qv, Qa, KE, clock, CMD, Fref, EF,
                ee, mo_e, np.array(np.broadcast_to(K, (3,))), chk_f, chk_i)
        return pre, post

    def _native_done(self, controller, nat, CMD, end) -> None:
        """After a compiled run: the plant's held command and the controller's state as the Python loop leaves them."""
        state, ist = nat[1][24], nat[1][25]
        self.u = CMD[end - 1, 0].copy()
        controller.state = state.tolist()
        controller.tick = int(ist[0])

    def _observables(self, Qp, Qv, Qa, KE, U, K) -> dict[str, np.ndarray]:
        """Vectorised :meth:`observe` over recorded ticks (time of tick k's end: (k + 1)·T)."""
        N = Qp.shape[0]
        p = Qp[:, self._ee_pos]
        v = Qv[:, self._ee_dof]
        if self._hand is not None:
            hd = self.mj.hand_dof
            t = (np.arange(N) + 1) * self.period
            arg = self._w * t[:, None] + self._phase
            ref = self._offset + self._amp * np.sin(arg)
            dref = self._amp * self._w * np.cos(arg)
            hs = self._hand
            hand = hs.stiffness * (ref - Qp[:, self.mj.hand_qpos]) + hs.damping * (dref - Qv[:, hd]) - hs.mass * Qa[:, hd]
        else:
            hand = np.zeros((N, 3))
        if self.mj.motor_qpos is None:
            defl = np.zeros((N, 3))
        else:
            defl = Qp[:, self.mj.motor_qpos] - Qp[:, self.mj.slider_qpos]
        if self.ideal:
            f = U.copy()
        elif self.rigid:
            dof = self._slider_dof
            xi = self.design.actuator.viscous if self.options.viscous_friction else 0.0
            f = self.gain * U - xi * Qv[:, dof] - self.design.actuator.motor_mass * Qa[:, dof]
        else:
            f = self.spring * defl
        energy = KE + 0.5 * self.spring * np.sum(defl**2, axis=-1) + 0.5 * np.sum(K * p**2, axis=-1)
        return {"position": p, "velocity": v, "hand_force": hand, "actuator_force": f @ self.JinvT.T,
                "energy": energy}

    def _window_bad(self, st, Qp, Qv, KE, clock, start, end, K, explode) -> int:
        """First bad tick in [start, end) by the reference loop's rule (−1: none)."""
        p = Qp[start:end][:, self._ee_pos]
        e = KE[start:end] + 0.5 * np.sum(K * p**2, axis=-1)
        if self.mj.motor_qpos is not None:
            defl = Qp[start:end][:, self.mj.motor_qpos] - Qp[start:end][:, self.mj.slider_qpos]
            e = e + 0.5 * self.spring * np.sum(defl**2, axis=-1)
        T = self.period
        reset = clock[start:end] < (np.arange(start, end) + 0.5) * T  # MuJoCo auto-reset (BADQACC)
        bad = reset | ~np.all(np.isfinite(p), axis=-1) | ~(e < explode) | ~np.all(np.abs(p) < 1.0, axis=-1)
        return int(start + np.argmax(bad)) if bad.any() else -1

    def _health_from(self, EF: np.ndarray, Qp: np.ndarray) -> None:
        """Worst health over the recorded end-of-tick states (same quantities as :meth:`_check`)."""
        viol = float(np.abs(EF).max()) if EF.size else 0.0
        rot = closure = 0.0
        if Qp.shape[0]:
            ee = Qp[:, self.mj.ee_qpos]
            if self._free:  # free joint: position, then the unit quaternion (scalar first)
                rot = float(2.0 * np.arccos(np.minimum(1.0, np.abs(ee[:, 3]))).max())
            dz = Qp[:, self.mj.slider_qpos]  # output sliders from home
            closure = float(np.linalg.norm(ee[:, :3] - dz @ self._J.T, axis=-1).max())
        self._worst = [viol, rot, closure]

    @property
    def health(self) -> Health:
        """Worst closed-chain health since the last reset."""
        return Health(violation=self._worst[0], rotation=self._worst[1], closure=self._worst[2])

    def warnings(self) -> tuple[str, ...]:
        """Names and counts of the MuJoCo warnings raised since the last reset."""
        out = []
        for i, w in enumerate(self.data.warning):
            if w.number > 0:
                out.append(f"{self._mujoco.mjtWarning(i).name} x{w.number}")
        return tuple(out)


# ------------------------------------------------------------------------------- closed loop
@dataclass(frozen=True, kw_only=True)
class MultibodyResult:
    """A closed-loop run on the multibody plant: the runner's result + constraint health."""

    loop: Any  # hapticopt.analysis.prrr.loop.closed_loop.ClosedLoopResult
    health: Health
    warnings: tuple[str, ...]
    substeps: int
    timestep: float  # [s]
    integrator: str
    platform: str
    link_masses: str
    reason: str
    wall_time: float  # [s]
    status: Status
    message: str
    loop_engine: str = "python"  # "compiled" (numba) or "python"
    loop_reason: str = ""  # why that engine ran

    @property
    def health_ok(self) -> bool:
        return self.health.violation <= VIOLATION_TOL and self.health.rotation <= ROTATION_TOL

    @property
    def notes(self) -> tuple[str, ...]:
        return self.loop.notes

    @property
    def traces(self) -> Any:
        return self.loop.traces

    def metrics(self) -> dict[str, Any]:
        out = dict(self.loop.metrics())
        out.update(self.health.metrics())
        out.update({
            "backend": "multibody", "backend_reason": self.reason, "constraint_health_ok": self.health_ok,
            "mujoco_warnings": list(self.warnings), "plant_substeps": self.substeps,
            "mujoco_timestep_ms": self.timestep * 1e3, "mujoco_integrator": self.integrator,
            "platform_model": self.platform, "link_masses": self.link_masses, "wall_time_s": self.wall_time,
            "closed_loop_engine": self.loop_engine if self.loop_engine == "compiled" else f"python: {self.loop_reason}",
        })
        return out


def simulate(design: PrrrDesign, scene: Scene, *, fidelity: Fidelity = Fidelity.STANDARD,
             platform: Platform = Platform.FREE, link_masses: LinkMasses | None = None,
             solver: SolverSettings | None = None, reason: str | None = None,
             compute: Compute = DEFAULT) -> MultibodyResult:
    """Run ``scene`` on ``design`` with the firmware controller in the loop on the MuJoCo plant (``compute``: which
    tick loop runs, see :meth:`MujocoPlant.run`)."""

    res = resolve(scene, force=Backend.MULTIBODY)
    # the runner's setup (controller, gains, ticks, energy scale) is backend-independent; it is
    # built on the scene without link_dynamics, which only the plant needs
    lumped_scene = dataclasses.replace(scene, effects=scene.effects - {Effect.LINK_DYNAMICS})
    st = closed_loop.setup(design, lumped_scene, fidelity=fidelity)
    options = model_options(scene, res, fidelity=fidelity, platform=platform, link_masses=link_masses)
    if solver is not None:
        options = dataclasses.replace(options, solver=solver)
    plant = MujocoPlant(design, scene, options, period=st.period, interpolation=st.cfg.interpolation)
    plant.enable_energy()
    st = dataclasses.replace(st, resolution=res, substeps=plant.substeps)
    controller = firmware_controller(st.cfg, st.gains)
    t0 = time.perf_counter()
    traces = plant.run(controller, st, compute=compute)
    wall = time.perf_counter() - t0
    loop = closed_loop.metrics_from_traces(traces, st, 0, backend="multibody", wall_time=wall)
    warns = plant.warnings()
    status, message = loop.status, loop.message
    health = plant.health
    problems = []
    if health.violation > VIOLATION_TOL:
        problems.append(f"constraint violation {health.violation * 1e3:.3g} mm > {VIOLATION_TOL * 1e3:g} mm")
    if health.rotation > ROTATION_TOL:
        problems.append(f"platform rotation {health.rotation * 1e3:.3g} mrad > {ROTATION_TOL * 1e3:g} mrad")
    if warns:
        problems.append("MuJoCo warnings: " + ", ".join(warns))
    if problems:
        message = "; ".join(([message] if message else []) + problems)
        if status == Status.OK:
            status = Status.FAILED
    return MultibodyResult(
        loop=loop, health=health, warnings=warns, substeps=plant.substeps, timestep=float(plant.model.opt.timestep),
        integrator=options.solver.integrator.value, platform=options.platform.value,
        link_masses=options.link_masses.value, reason=reason or res.reason, wall_time=wall,
        status=status, message=message, loop_engine=plant.loop_engine, loop_reason=plant.loop_reason,
    )


def warm_up() -> str | None:
    """Load (or compile) the compiled MuJoCo loops of both devices now (zero ticks each); returns why they are
    unavailable (None: ready). For a worker to call at start."""
    reason = mc.warm_up()
    if reason is None:
        from hapticopt.analysis.prrr.loop import _mujoco_kernel  # numba

        _mujoco_kernel.warm()
    return reason
