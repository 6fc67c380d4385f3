"""Time-domain check of the transparency bandwidth: a MuJoCo sine sweep with a 1 kHz firmware.

The hand is a stiff spring-damper (applied force on the handle body) that drives the handle
along x_d(t) = x0 + e·X·sin ωt. The firmware samples the actuated joints every
``hold_period``, renders the virtual spring F_D = −K(p − x0) by τ = Jᵀ F_D and holds τ
(zero-order hold) until the next sample. At each frequency the transparency is the ratio of
the fundamentals of the force felt by the hand, F_H = −F_hand, and of the ideal force
−K·e·(x − x0), both along e, over whole periods after one settling period. The bandwidth is
where |G_T| crosses 0 ± 3 dB, interpolated (in log f) between the swept frequencies, which
bracket the frequency-domain prediction of :mod:`hapticopt.analysis.master.transparency`.

Uses the closed-chain MJCF of :func:`hapticopt.design.master.mjcf.master_mjcf` (parallelogram closed by
an equality constraint, solref 2 ms, timestep 0.25 ms, implicitfast). This sweep renders open loop
(no dynamics compensation): its setup defaults to :data:`OPEN_LOOP_1KHZ`; seed 003's compensating
controller runs in the firmware's scenes (:mod:`hapticopt.analysis.master.mujoco_plant`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from hapticopt.analysis.master import dynamics_numpy as mn
from hapticopt.analysis.master import transparency as mt
from hapticopt.design.master.params import MasterDesign
from hapticopt.analysis.master import dynamics as md
from hapticopt.design.master.mjcf import full_qpos
from hapticopt.design.master.mjcf import master_mjcf

_DB3 = np.sqrt(2.0)  # ±3 dB as half/double power, as hapticopt.analysis.master.transparency


@dataclass(frozen=True, kw_only=True)
class SweepResult:
    """Sine-sweep transparency along one axis [SI]."""

    axis: str
    frequencies: np.ndarray  # [Hz]
    gain: np.ndarray  # |G_T| measured
    bandwidth: float  # [Hz] time domain
    predicted: float  # [Hz] frequency domain (same pose and setup)
    wall_time: float  # [s]
    closure_error: float  # max parallelogram closure error during the runs [m]

    @property
    def relative_error(self) -> float:
        return abs(self.bandwidth - self.predicted) / self.predicted


def _gain_at(model_mj, data, design: MasterDesign, kin, q0: np.ndarray, x0: np.ndarray, e: np.ndarray, f: float,
             setup: mt.RenderingSetup, timestep: float, hand_stiffness: float, hand_damping: float) -> tuple[float, float]:
    import mujoco


    mujoco.mj_resetData(model_mj, data)
    data.qpos[:] = full_qpos(q0)
    mujoco.mj_forward(model_mj, data)
    w = 2 * np.pi * f
    X = setup.amplitude
    K = setup.spring
    period = 1.0 / f
    n_steps = int(round(3 * period / timestep))
    n_settle = int(round(period / timestep))
    hold_steps = max(1, int(round(setup.hold_period / timestep))) if setup.hold_period > 0 else 1
    handle = model_mj.body("handle").id
    site = model_mj.site("handle").id
    rear = model_mj.site("forearm_rear").id
    coupler = model_mj.body("coupler").id
    L5 = design.geometry.upper_arm
    idx = [model_mj.joint(n).qposadr[0] for n in ("theta1", "theta2", "theta3")]
    tau = np.zeros(3)
    t_arr, fh, fd = [], [], []
    closure = 0.0
    for k in range(n_steps):
        t = k * timestep
        if k % hold_steps == 0:
            q = data.qpos[idx]
            rho = L5 * np.cos(q[1]) + design.geometry.forearm * np.sin(q[2])
            p = np.array([rho * np.cos(q[0]), rho * np.sin(q[0]),
                          design.geometry.shoulder_height + L5 * np.sin(q[1]) - design.geometry.forearm * np.cos(q[2])])
            J = mn.jacobian(kin, q[None])[0]
            tau = J.T @ (-K * (p - x0))
        data.ctrl[:] = tau
        x = data.site_xpos[site]
        v = np.zeros(6)
        mujoco.mj_objectVelocity(model_mj, data, mujoco.mjtObj.mjOBJ_SITE, site, v, 0)
        xd = x0 + e * X * np.sin(w * t)
        vd = e * X * w * np.cos(w * t)
        f_hand = hand_stiffness * (xd - x) + hand_damping * (vd - v[3:])
        data.xfrc_applied[handle, :3] = f_hand
        if k >= n_settle:
            t_arr.append(t)
            fh.append(-f_hand @ e)
            fd.append(-K * ((x - x0) @ e))
            cend = data.xpos[coupler] + data.xmat[coupler].reshape(3, 3) @ np.array([L5, 0.0, 0.0])
            closure = max(closure, float(np.linalg.norm(cend - data.site_xpos[rear])))
        mujoco.mj_step(model_mj, data)
    t_arr = np.asarray(t_arr)
    ph = np.exp(-1j * w * t_arr)
    return float(abs(np.sum(np.asarray(fh) * ph) / np.sum(np.asarray(fd) * ph))), closure


#: the open-loop 1 kHz rendering this sweep implements
OPEN_LOOP_1KHZ = mt.RenderingSetup(compensation=mt.OPEN_LOOP, hold_period=mt.HOLD_PERIOD_S)


def sweep(design: MasterDesign, axis: str = "x", *, pose: np.ndarray | None = None,
          setup: mt.RenderingSetup | None = None, factors: tuple[float, ...] = (0.85, 0.95, 1.05, 1.15),
          timestep: float = 2.5e-4, hand_stiffness: float = 3000.0) -> SweepResult:
    """Sine sweep along ``axis`` ('x' or 'z') around the frequency-domain bandwidth."""
    import mujoco


    setup = OPEN_LOOP_1KHZ if setup is None else setup
    if setup.compensation != mt.OPEN_LOOP:
        raise ValueError("analysis.master.sweep renders open loop only: use mt.OPEN_LOOP (the compensating "
                         "controller runs in the master scenes)")
    a = mt.AXES.index(axis)
    e = np.eye(3)[[0, 2][a]]
    q0 = mt.default_pose(design) if pose is None else np.asarray(pose, dtype=float)
    model = md.model_of(design)
    fd_res = mt.evaluate(design, setup=setup, pose=q0, model=model)
    predicted = fd_res.bandwidth[a]
    lam = max(fd_res.apparent_mass[a], 1e-6)
    hand_damping = 2.0 * np.sqrt(hand_stiffness * lam)
    t0 = time.perf_counter()
    model_mj = mujoco.MjModel.from_xml_string(master_mjcf(design, timestep=timestep))
    data = mujoco.MjData(model_mj)
    data.qpos[:] = 0

    data.qpos[:] = full_qpos(q0)
    mujoco.mj_forward(model_mj, data)
    x0 = data.site_xpos[model_mj.site("handle").id].copy()
    freqs = predicted * np.asarray(factors)
    gains, closure = [], 0.0
    for f in freqs:
        g, c = _gain_at(model_mj, data, design, model.kin, q0, x0, e, float(f), setup, timestep, hand_stiffness,
                        hand_damping)
        gains.append(g)
        closure = max(closure, c)
    gains = np.asarray(gains)
    bw = _crossing(freqs, gains)
    return SweepResult(axis=axis, frequencies=freqs, gain=gains, bandwidth=bw, predicted=float(predicted),
                       wall_time=time.perf_counter() - t0, closure_error=closure)


def _crossing(freqs: np.ndarray, gains: np.ndarray) -> float:
    """First frequency where the gain leaves [1/√2·…, √2·…] (±3 dB), log-linear interpolation; NaN-free."""
    out = (gains > _DB3) | (gains < 1.0 / _DB3)
    if not out.any():
        return float(freqs[-1])
    k = int(np.argmax(out))
    if k == 0:
        return float(freqs[0])
    bound = _DB3 if gains[k] > _DB3 else 1.0 / _DB3
    g0, g1 = np.log(gains[k - 1]), np.log(gains[k])
    s = (np.log(bound) - g0) / (g1 - g0)
    return float(np.exp(np.log(freqs[k - 1]) + s * (np.log(freqs[k]) - np.log(freqs[k - 1]))))
