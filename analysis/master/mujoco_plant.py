"""The surgical master (seed 003) in closed loop: its firmware against the MuJoCo multibody plant.

Plant: the MJCF of :func:`hapticopt.design.master.mjcf.master_mjcf` (turret, upper arm, driver link,
parallelogram coupler closed by an equality ``connect``, forearm, handle, counterweights, joint
motors) with the scene's effects applied after compiling: gravity on/off, joint viscous friction
(``viscous_friction``), Coulomb friction (``coulomb_friction``, MuJoCo ``frictionloss``), rotor
inertia (``motor_dynamics``, joint armature), the motor torque limit (``saturation``). The
solver settings are the 3-PRRR plant's per fidelity (:data:`hapticopt.analysis.prrr.loop.mujoco_model.SOLVER_BY_FIDELITY`:
integrator, timestep, solref = 2·dt, solimp 0.9999) — the parallelogram closure is held to the
same tolerance (≤ 0.01 mm, reported with every run and flagged when exceeded).

The operator hand (``operator`` effect) is a body of mass m_h on three slides with springs k_h and
dampers b_h towards the reference motion x_r(t) = x0 + offset + A sin(2πft + φ) (seed 000 eq 1),
tied to the handle by a ``connect``; the reference is updated once per controller period at its
midpoint, as for the 3-PRRR plant. The force of the hand on the handle is
k_h(x_r − x_h) + b_h(ẋ_r − ẋ_h) − m_h ẍ_h.

The firmware (:class:`hapticopt.analysis.master.firmware.MasterController`) sees only the joint encoder
counts (rounded when ``quantization`` is on) and its torques are held for the period (ZOH, 1 kHz).

Scenes (``device = "master"``): a virtual spring or box (walls) around the start handle position
x0 + ``environment.anchor_mm``. With ``simulation.sweep_factors`` the scene is a sine sweep: one run
per frequency f = factor × the frequency-domain transparency bandwidth of
:mod:`hapticopt.analysis.master.transparency` (same pose, spring, amplitude, hold); the gain is the ratio of
the fundamentals of the force the hand feels, −F_hand·e, and of the ideal force −K e·(x − x_r),
over whole periods after the first; the bandwidth is the ±3 dB crossing (log interpolation, as
:mod:`hapticopt.analysis.master.sweep`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hapticopt.analysis.loop.traces import OVERSAMPLE, SATURATION_FRACTION, SATURATION_WINDOW_S, Traces
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.master.firmware import MasterController, MasterFirmwareConfig
from hapticopt.analysis.compute import DEFAULT, Backend as ComputeBackend, Compute
from hapticopt.analysis.loop import mujoco_compiled as mc
from hapticopt.analysis.loop.mujoco_solver import SOLVER_BY_FIDELITY, Health, SolverSettings
from hapticopt.analysis.loop.scene import (
    DynamicsCompensation,
    Effect,
    EnvKind,
    FirmwareMode,
    Resolution,
    Scene,
    require_mode,
    resolve,
)
from hapticopt.analysis.status import Status
from hapticopt.design.errors import InvalidInput
from hapticopt.design.master.params import MasterDesign
from hapticopt.analysis.master.transparency import default_pose
from hapticopt.analysis.master import dynamics as md
from hapticopt.analysis.master import transparency as mt
from hapticopt.analysis.master.sweep import _crossing
from hapticopt.design.master.mjcf import master_mjcf
from hapticopt.design.master.mjcf import full_qpos

VIOLATION_TOL = 1e-5  # [m] parallelogram closure (issue 8: 0.01 mm)
RUNAWAY = 0.5  # [m] handle further than this from its start: unstable
_AXIS_NAMES = ("x", "y", "z")


def _v(x: Any) -> str:
    return " ".join(f"{float(c):.12g}" for c in np.ravel(x))


def master_xml(design: MasterDesign, res: Resolution, scene: Scene, solver: SolverSettings, x0: np.ndarray) -> str:
    """The master MJCF with the fidelity's solver settings and (operator on) the hand body."""

    xml = master_mjcf(design, gravity=Effect.GRAVITY in res.effects, timestep=solver.timestep)
    sol = f'solref="{_v(solver.solref)}" solimp="{_v(solver.solimp)}"'
    xml = xml.replace('integrator="implicitfast"', f'integrator="{solver.integrator.value}"')
    assert 'solref="0.002 1"' in xml
    xml = xml.replace('solref="0.002 1"', sol)
    if Effect.OPERATOR in res.effects:
        op = scene.operator
        joints = "".join(f'\n      <joint name="hand_{a}" type="slide" axis="{ax}" stiffness="{op.stiffness:.12g}" '
                         f'damping="{op.damping:.12g}"/>' for a, ax in zip("xyz", ("1 0 0", "0 1 0", "0 0 1")))
        mass = max(op.mass, 1e-6)
        hand = (f'    <body name="hand" pos="{_v(x0)}" gravcomp="1">{joints}\n'
                f'      <inertial pos="0 0 0" mass="{mass:.12g}" diaginertia="1e-6 1e-6 1e-6"/>\n'
                f'      <site name="hand_site" pos="0 0 0"/>\n    </body>\n')
        xml = xml.replace("  </worldbody>", hand + "  </worldbody>")
        xml = xml.replace("  </equality>", f'    <connect name="hand" site1="hand_site" site2="handle" {sol}/>\n'
                                           "  </equality>")
    return xml


def _as_slice(idx: np.ndarray) -> slice | np.ndarray:
    """``idx`` as a slice when it is a contiguous ascending run (a slice reads and writes without a copy)."""
    idx = np.asarray(idx)
    if idx.size and np.all(np.diff(idx) == 1):
        return slice(int(idx[0]), int(idx[-1]) + 1)
    return idx


def _one_hot(sel: Any) -> bool:
    """Whether every row of a body-to-frame selection is one-hot (each body on exactly one link frame)."""
    sel = np.asarray(sel)
    return sel.ndim == 2 and bool(np.all((sel == 0.0) | (sel == 1.0)) and np.all(sel.sum(axis=1) == 1.0))


#: largest relative residual of the compensation model's M̂ in the compiled law's trig basis
#: (``_mujoco_kernels.mass_basis_residual``): M̂ is in the basis for every one-hot model (measured 6e-16 on master-paper,
#: 5e-16 with random CoMs and full inertia tensors); a model outside it misses by O(1)
MASS_BASIS_RESIDUAL = 1e-12


def _compensation_bodies(controller: MasterController) -> tuple[np.ndarray, ...]:
    """The compensation model's bodies (:class:`hapticopt.analysis.master.dynamics.MassModel`) as the kernels' plain
    arrays: (L5, L4, d, h), frame per body, weight, mass, CoM (b, 3), inertia (b, 3, 3), rotor inertia (3,)."""
    cm = controller.cfg.compensation_model
    kin = np.array([float(cm.kin.upper_arm), float(cm.kin.forearm), float(cm.kin.driver_link),
                    float(cm.kin.shoulder_height)])
    return (kin, np.ascontiguousarray(np.argmax(np.asarray(cm.frame), axis=1), dtype=np.intp),
            np.array(controller._weights, dtype=np.float64), np.array(cm.mass, dtype=np.float64),
            np.array(cm.com, dtype=np.float64).reshape(-1, 3), np.array(cm.inertia, dtype=np.float64).reshape(-1, 3, 3),
            np.array(np.broadcast_to(np.asarray(cm.rotor_inertia, dtype=np.float64), (3,))))


def start_pose(design: MasterDesign) -> np.ndarray:
    """Calibration / start pose of the master scenes: the middle of the θ3 and φ ranges."""

    return default_pose(design)


class MasterPlant:
    """The MuJoCo master with the hand; advanced a controller period at a time."""

    backend = "multibody"

    def __init__(self, design: MasterDesign, scene: Scene, res: Resolution, *, period: float,
                 fidelity: Fidelity = Fidelity.STANDARD, solver: SolverSettings | None = None) -> None:
        import mujoco


        self._mujoco = mujoco
        self.design, self.scene, self.res = design, scene, res
        self.solver = solver or SOLVER_BY_FIDELITY[fidelity]
        self.q0 = start_pose(design)
        # the handle's start position from the arm alone (the hand body is placed there)
        arm = mujoco.MjModel.from_xml_string(_arm_only(design, res, scene, self.solver))
        ad = mujoco.MjData(arm)
        ad.qpos[:] = full_qpos(self.q0)
        mujoco.mj_forward(arm, ad)
        self.x0 = ad.site_xpos[arm.site("handle").id].copy()
        self.model = m = mujoco.MjModel.from_xml_string(master_xml(design, res, scene, self.solver, self.x0))
        self.data = mujoco.MjData(m)
        fx = res.effects
        act = [m.joint(n).dofadr[0] for n in ("theta1", "theta2", "theta3")]
        self.act_qpos = np.array([m.joint(n).qposadr[0] for n in ("theta1", "theta2", "theta3")])
        if Effect.VISCOUS_FRICTION not in fx:
            m.dof_damping[act] = 0.0
        if Effect.COULOMB_FRICTION not in fx:
            m.dof_frictionloss[act] = 0.0
        if Effect.MOTOR_DYNAMICS not in fx:
            m.dof_armature[act] = 0.0
        if Effect.SATURATION not in fx:
            m.actuator_ctrllimited[:] = 0
        # plant steps per controller period: the scene's ``simulation.substeps`` if set, else by fidelity
        self.substeps = scene.substeps if scene.substeps > 0 else max(1, int(round(period / self.solver.timestep)))
        m.opt.timestep = period / self.substeps
        self.period = period
        self.hand = Effect.OPERATOR in fx
        if self.hand:
            self.hand_qpos = np.array([m.joint(f"hand_{a}").qposadr[0] for a in "xyz"])
            self.hand_dof = np.array([m.joint(f"hand_{a}").dofadr[0] for a in "xyz"])
        self.site = m.site("handle").id
        self.n_closure = 3  # the parallelogram connect's rows come first
        self._full_q0 = full_qpos(self.q0)
        self.loop_engine, self.loop_reason = "python", "run() not called yet"
        self._basis_key: tuple | None = None  # the compensation model whose M̂ basis coefficients are in _basis
        self._basis: tuple[np.ndarray, float] = (np.zeros((13, 6)), 0.0)  # (13 basis functions, 6 entries), residual
        self._comp_coef = np.zeros((13, 6))  # what the kernel gets (zeros without compensation)

    def reset(self) -> None:
        mj, d = self._mujoco, self.data
        mj.mj_resetData(self.model, d)
        d.qpos[:len(self._full_q0)] = self._full_q0
        mj.mj_forward(self.model, d)

    def warnings(self) -> tuple[str, ...]:
        return tuple(f"{self._mujoco.mjtWarning(i).name} x{w.number}" for i, w in enumerate(self.data.warning)
                     if w.number > 0)

    def _kernels(self, controller: MasterController, compute: Compute, ticks: int) -> Any:
        """The compiled kernels when they can run ``controller`` (else None); records the engine and why."""
        cfg = controller.cfg
        why = None
        if not compute.use_numba(ticks, 1):
            why = f"compute backend {compute.backend.value}: the Python loop"
        elif type(controller) is not MasterController:
            why = f"controller {type(controller).__name__} has no compiled law (MasterController has)"
        elif cfg.compensation_model is not None and not _one_hot(cfg.compensation_model.frame):
            why = "the compensation model's bodies are not each on one link frame (the compiled law selects one)"
        elif cfg.env not in (EnvKind.FREE, EnvKind.SPRING, EnvKind.BOX):
            why = f"environment {cfg.env.value} has no compiled law"
        elif not np.array_equal(np.asarray(cfg.q0, dtype=float), self.q0):
            why = "the controller was homed at another pose than the plant's start"
        else:
            why = mc.availability()
            if why is not None and compute.backend is ComputeBackend.NUMBA:
                raise RuntimeError(f"compute backend numba: {why}")
        self._comp_coef = np.zeros((13, 6))
        if why is None and cfg.compensation_model is not None:
            kc = mc.kernels()
            body = _compensation_bodies(controller)
            key = tuple((a.shape, a.dtype.str, a.tobytes()) for a in body)
            if key != self._basis_key:  # identified once per compensation model (≈ 0.3 ms), not per run
                coef = kc.mass_basis(*body)
                self._basis_key, self._basis = key, (coef, kc.mass_basis_residual(coef, *body))
            coef, resid = self._basis
            if not resid <= MASS_BASIS_RESIDUAL:  # also NaN
                why = (f"the compensation model's mass matrix is not in the compiled law's trig basis (relative "
                       f"residual {resid:.3g} > {MASS_BASIS_RESIDUAL:g})")
            else:
                self._comp_coef = coef
        self.loop_engine = "python" if why else "compiled"
        self.loop_reason = why or "compiled loop (numba): firmware law and mj_step in one native loop"
        return None if why else mc.kernels()

    def _native_args(self, controller, quantize, delay_ticks, REF, DREF, P, TAU, FREF, EF, has_ef, clock,
                     HQ, HV, HA, EQF):
        """Arguments of :func:`master_chunk`: (before start/end/nstep, after)."""
        m, d, cfg = self.model, self.data, controller.cfg
        lay, kc = mc.layout(), mc.kernels()
        off = np.array([lay.time, lay.nefc, lay.efc_pos, lay.efc_force, lay.efc_type, lay.efc_id], dtype=np.int64)
        ip = lambda x: np.ascontiguousarray(x, dtype=np.intp)  # noqa: E731
        f3 = lambda x: np.array(np.broadcast_to(np.asarray(x, dtype=np.float64), (3,)))  # noqa: E731  (a writable copy: one kernel type)
        if self.hand:
            hq, hd = ip(self.hand_qpos), ip(self.hand_dof)
            eq_hand, eq_type = m.equality("hand").id, int(self._mujoco.mjtConstraint.mjCNSTR_EQUALITY)
        else:
            hq = hd = np.zeros(3, dtype=np.intp)
            REF = DREF = np.zeros((1, 3))
            eq_hand, eq_type = -1, -1
        env = {EnvKind.FREE: kc.ENV_FREE, EnvKind.SPRING: kc.ENV_SPRING, EnvKind.BOX: kc.ENV_BOX}[cfg.env]
        par = np.array([cfg.counts_per_rev / (2.0 * math.pi), controller._scale, cfg.period, cfg.velocity_alpha,
                        cfg.upper_arm, cfg.forearm, cfg.shoulder_height, cfg.wall_stiffness, cfg.wall_damping,
                        cfg.torque_limit, cfg.gravity_g1, cfg.gravity_g2])
        comp = cfg.compensation_model is not None
        flg = np.array([quantize, env, cfg.gravity_compensation, cfg.saturation, self.hand, self.n_closure,
                        eq_hand, eq_type, delay_ticks, comp], dtype=np.int64)
        st = np.zeros(18)
        st[0:3] = controller._p_prev
        st[3:6] = controller._v
        st[9:12], st[12:15], st[15:18] = controller._q_prev, controller._qd, controller._qdd
        ist = np.array([0, controller._samples], dtype=np.int64)
        dbuf = np.zeros((max(1, delay_ticks), 3))
        pre = (m._address, d._address, off)
        post = (d.qpos, d.qvel, d.qacc, d.ctrl, m.qpos_spring, d.qfrc_applied, d.site_xpos, int(self.site),
                ip(self.act_qpos), hq, hd, REF, DREF, par, flg, f3(cfg.q0), f3(controller._K), f3(controller._B),
                f3(controller._anchor), f3(controller._half), st, ist, dbuf,
                P, TAU, FREF, EF, has_ef, clock, HQ, HV, HA, EQF, f3(self.x0), np.array([RUNAWAY, self.period]), 100,
                self._comp_coef)
        return pre, post

    def run(self, controller: MasterController, *, ticks: int, frequency: float, quantize: bool,
            delay_ticks: int = 0, compute: Compute = DEFAULT) -> dict[str, np.ndarray]:
        """Closed loop for ``ticks`` periods with the hand reference at ``frequency`` [Hz]; raw records.

        ``compute``: the ticks run in the compiled loop of :mod:`hapticopt.analysis.loop.mujoco_compiled` (unless it
        says numpy; with numba, an unavailable loop raises) when it can run this controller — bit-identical records without dynamics compensation; with it (Ĉ q̂̇ in
        closed form there, by central differences of M̂ here) within the reference's own rounding envelope
        (docs/performance.md §2); else in Python. :attr:`loop_engine` / :attr:`loop_reason` say which ran and why."""
        mj, m, d = self._mujoco, self.model, self.data
        self.reset()
        scale = controller.cfg.counts_per_rev / (2.0 * math.pi)
        qa = self.act_qpos
        q0 = self.q0

        qpos_ = d.qpos
        rint = np.rint  # what np.round does at 0 decimals, without its wrapper

        def counts() -> np.ndarray:
            c = (qpos_[qa] - q0) * scale
            return rint(c) if quantize else c

        controller.reset(counts())
        mo = self.scene.motion
        w = 2.0 * math.pi * frequency
        amp, off, ph = np.asarray(mo.amplitude), np.asarray(mo.offset), np.asarray(mo.phase)
        T = self.period
        N = ticks
        P, V, FH, TAU, FREF = (np.zeros((N, 3)) for _ in range(5))
        EF = np.zeros(N)
        clock = np.zeros(N)
        delay = [np.zeros((1, 3))] * delay_ticks
        if self.hand:
            op = self.scene.operator
            hq, hd = self.hand_qpos, self.hand_dof
            tm = (np.arange(N) + 0.5) * T
            REF = off + amp * np.sin(w * tm[:, None] + ph)
            DREF = op.damping * amp * w * np.cos(w * tm[:, None] + ph)
            HQ, HV, HA, EQF = (np.zeros((N, 3)) for _ in range(4))
            eq_hand = m.equality("hand").id
            eq_type = int(mj.mjtConstraint.mjCNSTR_EQUALITY)
        stop = -1
        n = self.n_closure
        # per tick only raw values are copied into preallocated rows; views and slices are made once
        qpos, qvel, qacc, ctrl = d.qpos, d.qvel, d.qacc, d.ctrl
        xsite = d.site_xpos[self.site]  # a view: MuJoCo updates it in place
        has_ef = np.zeros(N, dtype=bool)
        if self.hand:
            hq, hd = _as_slice(hq), _as_slice(hd)
            qs, qfa = m.qpos_spring, d.qfrc_applied
        hand_rows: slice | np.ndarray | None = None  # efc rows of the hand's connect
        hand_ne = -1  # d.ne they were found at
        step = mj.mj_step
        substeps = self.substeps
        kern = self._kernels(controller, compute, ticks)
        # the Python loop's closure residual rows (|·|.max per tick after the loop; the compiled loop writes the max)
        EFR = np.zeros((N, n)) if kern is None else None
        if kern is not None:
            nat = self._native_args(controller, quantize, delay_ticks, REF if self.hand else None,
                                    DREF if self.hand else None, P, TAU, FREF, EF, has_ef, clock,
                                    *((HQ, HV, HA, EQF) if self.hand else (np.zeros((1, 3)),) * 4))
            lo = 0
            while lo < N:  # windows on until one holds a possibly bad tick (checked exactly here) or N
                hi = kern.master_chunk(*nat[0], lo, N, substeps, *nat[1])
                if hi < 0:  # no tick was possibly bad: none is (the prefilter is conservative)
                    break
                lo = ((hi - 1) // 100) * 100  # the Python loop's check window [lo, lo + 100) holding it
                bad = (~np.all(np.isfinite(P[lo:hi]), axis=-1)
                       | np.any(np.abs(P[lo:hi] - self.x0) > RUNAWAY, axis=-1)
                       | (clock[lo:hi] < (np.arange(lo, hi) + 0.5) * T))
                if bad.any():
                    stop = lo + int(np.argmax(bad))
                    break
                lo = hi
            st, ist = nat[1][20], nat[1][21]
            controller._p_prev, controller._v, controller.last_force = st[0:3].copy(), st[3:6].copy(), st[6:9].copy()
            if controller.cfg.compensation_model is not None:
                controller._q_prev, controller._qd, controller._qdd = st[9:12].copy(), st[12:15].copy(), st[15:18].copy()
                controller._samples = int(ist[1])
        for k in range(N) if kern is None else ():
            cmd = controller.step(counts())
            if delay:
                delay.append(cmd)
                cmd = delay.pop(0)
            ctrl[:] = cmd[0]
            if self.hand:
                qs[hq] = REF[k]
                qfa[hd] = DREF[k]
            step(m, d, substeps)
            P[k] = xsite
            TAU[k] = cmd[0]
            FREF[k] = controller.last_force
            efc_pos = d.efc_pos
            if efc_pos.shape[0] >= n:
                EFR[k] = efc_pos[:n]
                has_ef[k] = True
            clock[k] = d.time
            if self.hand:
                HQ[k], HV[k], HA[k] = qpos[hq], qvel[hd], qacc[hd]
                ne = d.ne
                if ne != hand_ne:  # the equality rows lead efc in equality order: found again when they change
                    rows = np.nonzero((d.efc_type == eq_type) & (d.efc_id == eq_hand))[0]
                    hand_rows = _as_slice(rows) if rows.size == 3 else None
                    hand_ne = ne
                if hand_rows is not None:  # the connect's force on the hand (body1); the handle feels its opposite
                    EQF[k] = -d.efc_force[hand_rows]
            if k % 100 == 99 or k == N - 1:
                lo = max(0, k - 99)
                bad = (~np.all(np.isfinite(P[lo:k + 1]), axis=-1)
                       | np.any(np.abs(P[lo:k + 1] - self.x0) > RUNAWAY, axis=-1)
                       | (clock[lo:k + 1] < (np.arange(lo, k + 1) + 0.5) * T))
                if bad.any():
                    stop = lo + int(np.argmax(bad))
                    break
        if n and kern is None:  # (the compiled loop writes EF per tick, the same max)
            EF[has_ef] = np.abs(EFR[has_ef]).max(axis=-1)
        if self.hand:
            # the hand's force on the handle: the hand connect's constraint force, at the same instant as
            # the recorded handle position (kinematics and efc_force of the last substep's start). The
            # spring formula k_h(x_r − x_h) + b_h(ẋ_r − ẋ_h) − m_h ẍ_h gives the same fundamentals (issue 16).
            FH = EQF
            V = HV  # the hand is tied to the handle: its velocity is the handle's
        out = {"position": P, "velocity": V, "hand_force": FH, "torque": TAU, "force_reference": FREF,
               "violation": EF, "stop": np.array([stop]), "reference": off + amp * np.sin(w * ((np.arange(N) + 1) * T)[:, None] + ph)}
        if stop >= 0:
            for key in ("position", "velocity", "hand_force", "torque", "force_reference"):
                out[key][stop:] = out[key][stop - 1] if stop > 0 else 0.0
        return out


def _arm_only(design: MasterDesign, res: Resolution, scene: Scene, solver: SolverSettings) -> str:

    return master_mjcf(design, gravity=Effect.GRAVITY in res.effects, timestep=solver.timestep)


def controller_for(design: MasterDesign, scene: Scene, res: Resolution, x0: np.ndarray, q0: np.ndarray,
                   period: float) -> MasterController:

    env = scene.environment
    if env.kind not in (EnvKind.SPRING, EnvKind.BOX, EnvKind.FREE):
        raise InvalidInput(f"scene {scene.name}: environment.kind = {env.kind.value!r} is not rendered by the master "
                           "firmware: allowed free, spring, box")
    if env.kind == EnvKind.BOX and env.box_mode.value != "inside":
        raise InvalidInput(f"scene {scene.name}: environment.box_mode = {env.box_mode.value!r}: the master renders "
                           "walls around the handle (box_mode = \"inside\") only")
    fx = res.effects
    c = scene.controller
    g1 = g2 = 0.0
    gcomp = c.gravity_compensation and Effect.GRAVITY in fx
    if gcomp:
        gp = md.gravity_parameters(md.model_of(design))
        g1, g2 = float(gp.G1), float(gp.G2)
    g = design.geometry
    cfg = MasterFirmwareConfig(
        period=period, counts_per_rev=design.actuators.encoder_counts, q0=tuple(map(float, q0)),
        upper_arm=g.upper_arm, forearm=g.forearm, shoulder_height=g.shoulder_height, env=env.kind,
        anchor=tuple(map(float, x0 + np.asarray(env.anchor))), stiffness=env.stiffness, damping=env.damping,
        half_size=env.half_size, wall_stiffness=env.wall_stiffness, wall_damping=env.wall_damping,
        velocity_alpha=math.exp(-2 * math.pi * c.velocity_filter * period) if c.velocity_filter > 0 else 0.0,
        torque_limit=design.actuators.torque_limit, saturation=Effect.SATURATION in fx,
        quantized=Effect.QUANTIZATION in fx, gravity_compensation=gcomp, gravity_g1=g1, gravity_g2=g2,
        **_compensation(design, c.dynamics_compensation))
    return MasterController(cfg)


def _compensation(design: MasterDesign, which: DynamicsCompensation) -> dict[str, Any]:
    """The firmware's compensation model: the design's bodies, weighted per :class:`DynamicsCompensation`."""
    if which == DynamicsCompensation.NONE:
        return {}
    model = md.model_of(design)
    cw = np.asarray(model.counterweight, dtype=float)
    weights = np.ones_like(cw) if which == DynamicsCompensation.FULL else 1.0 - cw
    return {"compensation_model": model, "compensation_weights": tuple(map(float, weights))}


# ------------------------------------------------------------------------------------ results
@dataclass(frozen=True, kw_only=True)
class MasterResult:
    """A master scene run: metrics, parallelogram health, backend and reason."""

    scene: str
    stable: bool
    unstable_at: float | None
    measures: dict[str, Any]
    violation: float  # worst parallelogram closure residual [m]
    warnings: tuple[str, ...]
    effects: tuple[str, ...]
    notes: tuple[str, ...]
    reason: str
    substeps: int
    timestep: float
    integrator: str
    period: float
    wall_time: float
    status: Status
    message: str
    traces: Traces | None = field(default=None, repr=False, compare=False)
    loop_engine: str = "python"  # "compiled" (numba) or "python"
    loop_reason: str = ""  # why that engine ran

    @property
    def health(self) -> Health:
        return Health(violation=self.violation, rotation=0.0, closure=self.violation)

    @property
    def health_ok(self) -> bool:
        return self.violation <= VIOLATION_TOL

    def metrics(self) -> dict[str, Any]:
        out: dict[str, Any] = {"stable": self.stable, "unstable_at_s": self.unstable_at}
        out.update(self.measures)
        out.update({
            "backend": "multibody", "backend_reason": self.reason, "device": "master", "effects": list(self.effects),
            "constraint_violation_mm": self.violation * 1e3, "constraint_health_ok": self.health_ok,
            "mujoco_warnings": list(self.warnings), "controller_period_ms": self.period * 1e3,
            "plant_substeps": self.substeps, "mujoco_timestep_ms": self.timestep * 1e3,
            "mujoco_integrator": self.integrator, "wall_time_s": self.wall_time,
            "closed_loop_engine": self.loop_engine if self.loop_engine == "compiled" else f"python: {self.loop_reason}",
        })
        return out


def _setup(scene: Scene, ctl: MasterController, K: float, amp: float, T: float) -> mt.RenderingSetup:
    """The frequency-domain model of the scene's loop: its spring, amplitude, controller period
    (hold and derivative estimates at the rate the firmware runs) and compensation."""
    c = scene.controller
    return mt.RenderingSetup(spring=K, amplitude=amp, hold_period=T, estimator_filter=c.velocity_filter,
                             compensation=mt.Compensation(gravity=ctl.cfg.gravity_compensation,
                                                          inertia=c.dynamics_compensation))


def _fundamental(x: np.ndarray, t: np.ndarray, w: float) -> complex:
    return complex(np.sum(x * np.exp(-1j * w * t)))


def _fit(A: np.ndarray, y: np.ndarray) -> np.ndarray:
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    return coef


def simulate(design: MasterDesign, scene: Scene, *, fidelity: Fidelity = Fidelity.STANDARD, reason: str | None = None,
             solver: SolverSettings | None = None, compute: Compute = DEFAULT) -> MasterResult:
    """Run a master scene with the master firmware in the loop on the MuJoCo plant (``compute``: which tick loop
    runs, see :meth:`MasterPlant.run`)."""

    if getattr(design, "device", None) != "master":
        raise InvalidInput(f"scene {scene.name} is a master scene; design {getattr(design, 'name', '?')!r} is a "
                           f"{getattr(design, 'device', '?')}")
    require_mode(scene, FirmwareMode.IMPEDANCE, "the master's impedance firmware (IOIC: hapticopt.analysis.master.ioic)")
    res = resolve(scene)
    fx = res.effects
    T = scene.controller.period if Effect.SAMPLING in fx else scene.controller.period / OVERSAMPLE[fidelity]
    if Effect.OPERATOR not in fx:
        raise InvalidInput(f"scene {scene.name}: master scenes need the operator effect (the hand moves the handle)")
    t0 = time.perf_counter()
    plant = MasterPlant(design, scene, res, period=T, fidelity=fidelity, solver=solver)
    ctl = controller_for(design, scene, res, plant.x0, plant.q0, T)
    delay = int(round(scene.time_delay / T)) if Effect.TIME_DELAY in fx else 0
    ax = scene.measure_axis
    e = np.eye(3)[ax]
    measures: dict[str, Any] = {}
    runs = []
    if scene.sweep_factors:
        if scene.environment.kind != EnvKind.SPRING:
            raise InvalidInput(f"scene {scene.name}: a sweep (simulation.sweep_factors) renders a virtual spring: "
                               "set environment.kind = \"spring\"")
        if ax == 1:
            raise InvalidInput(f"scene {scene.name}: simulation.measure_axis = \"y\": the transparency sweep runs along "
                               "x or z (hapticopt.analysis.master.transparency)")
        K = scene.environment.stiffness[ax]
        amp = float(np.linalg.norm(scene.motion.amplitude))
        setup = _setup(scene, ctl, K, amp, T)
        pred = mt.evaluate(design, setup=setup, pose=plant.q0, model=md.model_of(design))
        predicted = float(pred.bandwidth[mt.AXES.index(_AXIS_NAMES[ax])])
        freqs = predicted * np.asarray(scene.sweep_factors)
        gains = []
        for f in freqs:
            n = int(round(scene.sweep_periods / f / T))
            r = plant.run(ctl, ticks=n, frequency=float(f), quantize=Effect.QUANTIZATION in fx, delay_ticks=delay, compute=compute)
            runs.append(r)
            if r["stop"][0] >= 0:
                gains.append(math.nan)
                continue
            per = int(round(1.0 / f / T))
            t = (np.arange(n) + 1) * T
            sl = slice(per, per * scene.sweep_periods)
            w = 2 * math.pi * f
            fh = -r["hand_force"][sl] @ e
            fd = -K * ((r["position"][sl] - ctl.cfg.anchor) @ e)
            gains.append(abs(_fundamental(fh, t[sl], w) / _fundamental(fd, t[sl], w)))
        g = np.asarray(gains)
        bw = _crossing(freqs, g) if np.all(np.isfinite(g)) else math.nan
        measures.update({
            "sweep_frequencies_Hz": [float(x) for x in freqs], "transparency_gain": [float(x) for x in g],
            "transparency_bandwidth_Hz": bw, "predicted_bandwidth_Hz": predicted,
            "bandwidth_error_pct": abs(bw - predicted) / predicted * 100 if predicted > 0 else None,
            "sweep_axis": _AXIS_NAMES[ax],
        })
    else:
        r = plant.run(ctl, ticks=max(1, int(round(scene.duration / T))), frequency=scene.motion.frequency,
                      quantize=Effect.QUANTIZATION in fx, delay_ticks=delay, compute=compute)
        runs.append(r)
        n = r["position"].shape[0]
        stop = int(r["stop"][0])
        end = n if stop < 0 else stop
        start = min(int(round(min(0.5, scene.duration / 3) / T)), max(0, end - 2))
        p, v, fh = r["position"][start:end], r["velocity"][start:end], r["hand_force"][start:end]
        anchor = np.asarray(ctl.cfg.anchor)
        if end - start >= 3:
            measures["handle_force_rms_N"] = float(np.sqrt(np.mean(np.sum(fh**2, -1))))
            measures["handle_force_peak_N"] = float(np.max(np.linalg.norm(fh, axis=-1)))
        env = scene.environment
        if env.kind == EnvKind.BOX and end - start >= 3:
            depth = np.abs(p - anchor) - np.asarray(env.half_size)
            measures["wall_penetration_mm"] = float(max(0.0, depth.max()) * 1e3)
            into = depth[:, ax] > 0.0
            if into.sum() >= 10:  # F_hand = K_b·depth·sgn + B v + c on the samples inside the wall
                sgn = np.sign(p[into, ax] - anchor[ax])
                coef = _fit(np.stack([depth[into, ax] * sgn, v[into, ax], np.ones(into.sum())], -1), fh[into, ax])
                measures["rendered_wall_stiffness_N_per_mm"] = float(coef[0]) * 1e-3
                measures["wall_stiffness_error_pct"] = abs(coef[0] - env.wall_stiffness) / env.wall_stiffness * 100
        elif env.kind == EnvKind.SPRING and end - start >= 3 and np.ptp(p[:, ax]) > 0:
            coef = _fit(np.stack([p[:, ax] - anchor[ax], v[:, ax], np.ones(len(p))], -1), fh[:, ax])
            measures["rendered_stiffness_N_per_mm"] = float(coef[0]) * 1e-3
            target = env.stiffness[ax]
            measures["stiffness_error_pct"] = abs(coef[0] - target) / target * 100 if target > 0 else None
            f = scene.motion.frequency
            per = int(round(1.0 / f / T)) if f > 0 else 0
            if per > 0 and stop < 0 and n >= 2 * per and ax != 1:
                # seed 003's G_T = F_H/F_D at the motion frequency: fundamentals over whole periods after the first
                t = (np.arange(n) + 1) * T
                sl = slice(per, per * (n // per))
                w = 2 * math.pi * f
                fh_e = -r["hand_force"][sl] @ np.eye(3)[ax]
                fd_e = -target * ((r["position"][sl] - anchor) @ np.eye(3)[ax])
                G = _fundamental(fh_e, t[sl], w) / _fundamental(fd_e, t[sl], w)
                amp = float(np.linalg.norm(scene.motion.amplitude))
                pred = mt.evaluate(design, setup=_setup(scene, ctl, target, amp, T), pose=plant.q0)
                Gp = complex(mt.transfer(pred.coefficients, np.array([f]), pred.setup)[0, mt.AXES.index(_AXIS_NAMES[ax]), 0])
                measures.update({"transparency_gain_at_motion": abs(G), "predicted_transparency_gain": abs(Gp),
                                 "transparency_gain_error_pct": abs(abs(G) - abs(Gp)) / abs(Gp) * 100,
                                 "transparency_bandwidth_predicted_Hz": float(pred.bandwidth[mt.AXES.index(_AXIS_NAMES[ax])])})
        sat = np.abs(r["torque"][:end]) >= design.actuators.torque_limit * (1 - 1e-12)
        measures["torque_saturated_fraction"] = float(sat.any(axis=-1).mean()) if end else 0.0
    wall = time.perf_counter() - t0
    # unstable: the run stopped (non-finite, runaway, MuJoCo reset), or the torques sat on the limit
    # for more than half of a 0.1 s window (a saturated limit cycle, e.g. a chattering stiff wall) —
    # the rules of hapticopt.analysis.prrr.loop.closed_loop.classify
    times = []
    for r in runs:
        if r["stop"][0] >= 0:
            times.append((int(r["stop"][0]) + 1) * T)
        elif Effect.SATURATION in fx:
            sat = np.any(np.abs(r["torque"]) >= design.actuators.torque_limit * (1 - 1e-12), axis=-1)
            W = max(1, int(round(SATURATION_WINDOW_S / T)))
            nwin = len(sat) // W
            if nwin:
                frac = sat[: nwin * W].reshape(nwin, W).mean(axis=1)
                if np.any(frac > SATURATION_FRACTION):
                    times.append((int(np.argmax(frac > SATURATION_FRACTION)) + 1) * W * T)
    stable = not times
    unstable_at = None if stable else times[0]
    violation = float(max(float(r["violation"].max()) for r in runs))
    warns = plant.warnings()
    status, problems = (Status.OK, []) if stable else (Status.UNSTABLE, [f"unstable: detected at t = {unstable_at:.4g} s"])
    if violation > VIOLATION_TOL:
        problems.append(f"parallelogram closure violation {violation * 1e3:.3g} mm > {VIOLATION_TOL * 1e3:g} mm")
    if warns:
        problems.append("MuJoCo warnings: " + ", ".join(warns))
    if problems and status == Status.OK:
        status = Status.FAILED
    last = runs[0]
    N = last["position"].shape[0]
    run_s = min(r["position"].shape[0] for r in runs) * T
    if status == Status.OK and run_s < SATURATION_WINDOW_S * (1.0 - 1e-9):
        # the saturation detector decides on SATURATION_WINDOW_S windows (as the 3-PRRR's closed loop):
        # a shorter run proves nothing (issue 37: 5–50 ms against a 1e9 N/mm wall were called ok)
        status, stable = Status.INCONCLUSIVE, False
        problems.append(f"the run lasted {run_s:.3g} s, shorter than the {SATURATION_WINDOW_S:g} s the instability "
                        "detector needs: no verdict")
    traces = Traces(period=T, energy=np.zeros((N, 1)), saturated=np.zeros((N, 1), dtype=bool),
                    stop_tick=last["stop"], position=last["position"][:, None], hand_force=last["hand_force"][:, None],
                    actuator_force=last["force_reference"][:, None], force_reference=last["force_reference"][:, None],
                    velocity=last["velocity"][:, None])
    return MasterResult(
        scene=scene.name, stable=stable, unstable_at=unstable_at, measures=measures, violation=violation,
        warnings=warns, effects=tuple(res.effect_names()), notes=res.notes, reason=reason or res.reason,
        substeps=plant.substeps, timestep=float(plant.model.opt.timestep), integrator=plant.solver.integrator.value,
        period=T, wall_time=wall, status=status, message="; ".join(problems), traces=traces,
        loop_engine=plant.loop_engine, loop_reason=plant.loop_reason)
