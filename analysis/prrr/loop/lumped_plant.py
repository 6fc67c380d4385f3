"""Lumped plant: the two-mass SEA model of seed 002 eq (6) per leg, coupled through M_e (eq 7).

Per leg i (slider space, positions from the home pose, x = D − D_e):

    M_m D̈ = η F − ξ Ḋ − k (D − D_e)                      (motor side)
    M_e D̈_e = k (D − D_e) + Jᵀ F_ext + λ                   (output side, 3 legs coupled)

with M_e = M JᵀJ (eq 7, exact for the 3-PRRR's rigid translational dynamics), F_ext the hand
force (operator: m_h p̈ + b_h(ṗ − ẋ_r) + k_h(p − x_r) = −F_ext, seed 000 eq 1, hand mass added to
M) and the weight −M g e_z, λ the Coulomb friction of the output sliders.

Integration: between substeps the linear part is exact (zero-order-hold discretisation with
``scipy.linalg.expm`` of the augmented matrix [[A, B, c], [0, 0, 0]]): the reference motion is a
linear oscillator inside the state, so a sinusoidal hand motion is exact too. Coulomb friction
is solved implicitly at the velocity level each substep (Moreau time stepping): the friction
impulse λ ∈ [−F_c, F_c]³ makes the end-of-substep velocity consistent (zero while stuck,
opposing motion while sliding); a box-constrained LCP in three unknowns solved by projected
Gauss–Seidel, warm-started. Saturation acts on the commands, which are piecewise constant, so
saturation events need no special treatment here.

Modes (from the resolved effects):
  FULL   sea_compliance + motor_dynamics: states [D, D_e, Ḋ, Ḋ_e]
  RIGID  no sea_compliance: motor rigidly on the output, (M_m I + M_e) D̈_e = ηF − ξḊ_e + …
  IDEAL  no motor_dynamics: the command is the spring force itself (ideal force source)
  LOCKED output sliders clamped (D_e ≡ 0): the force loop of eq 8
Operator (when on) appends the reference oscillator [y, ẏ] (3 + 3 states).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
import scipy.linalg

from hapticopt.design.prrr.cad import DEFAULT_BRANCH
from hapticopt.design.prrr.kinematics import jacobian, joint_rate_jacobian, params_of
from hapticopt.analysis.loop.scene import Effect, FrictionLocation, Resolution, Scene
from hapticopt.design.prrr.params import PrrrDesign
from hapticopt.design.units import GRAVITY



class PlantMode(StrEnum):
    FULL = "full"
    RIGID = "rigid"
    IDEAL = "ideal"
    LOCKED = "locked"


@dataclass(frozen=True, kw_only=True)
class LumpedModel:
    """Continuous-time linear part ẋ = A x + B_u u + B_λ λ + c and the state layout."""

    mode: PlantMode
    A: np.ndarray  # (n, n)
    Bu: np.ndarray  # (n, 3) commands
    Bl: np.ndarray  # (n, 3) friction forces on the output sliders
    c: np.ndarray  # (n,) constant inputs (weight, reference offset)
    Q: np.ndarray  # (n, n) energy quadratic form, E = ½ xᵀQx
    x0: np.ndarray  # (n,) initial state
    out_pos: slice | None  # D_e in x (None when locked)
    out_vel: slice | None
    motor_pos: slice | None  # D in x (None without motor dynamics / SEA)
    ref_pos: slice | None  # y (reference motion minus offset), operator only
    ref_vel: slice | None
    J: np.ndarray
    spring: float  # k [N/m]
    motor_mass: float
    viscous: float  # ξ actually present [N·s/m]
    efficiency: float
    hand_stiffness: float  # k_h (0 without operator)
    hand_damping: float
    hand_mass: float
    offset: np.ndarray  # reference offset o [m]
    coulomb: float  # F_c per slider [N] (0 when off or not on the sliders)
    friction_map: np.ndarray | None = None  # (m, 3) S: friction-coordinate rates w = S Ḋ_e (None: no friction)
    friction_limit: np.ndarray | None = None  # (m,) |μ_j| ≤ limit_j [N or N·m]; slider force Sᵀμ

    @property
    def n(self) -> int:
        return self.A.shape[0]


def build_model(design: PrrrDesign, scene: Scene, resolution: Resolution) -> LumpedModel:
    """The linear model of ``design`` with the effects of ``resolution``."""
    fx = resolution.effects
    a = design.actuator
    J = jacobian(design.geometry.beta, xp=np)
    JtJ = J.T @ J
    eye = np.eye(3)
    k, Mm, eta = a.spring, a.motor_mass, a.efficiency
    xi = a.viscous if Effect.VISCOUS_FRICTION in fx else 0.0
    M = design.end_effector.mass
    op = Effect.OPERATOR in fx
    mh, bh, kh = (scene.operator.mass, scene.operator.damping, scene.operator.stiffness) if op else (0.0, 0.0, 0.0)
    offset = np.asarray(scene.motion.offset) if op else np.zeros(3)
    if scene.output_locked:
        mode = PlantMode.LOCKED
    elif Effect.MOTOR_DYNAMICS not in fx:
        mode = PlantMode.IDEAL
    elif Effect.SEA_COMPLIANCE not in fx:
        mode = PlantMode.RIGID
    else:
        mode = PlantMode.FULL
    Mout = (M + mh) * JtJ
    Khand, Chand = kh * JtJ, bh * JtJ
    weight = np.array([0.0, 0.0, -M * GRAVITY]) if Effect.GRAVITY in fx else np.zeros(3)
    bias_out = J.T @ (kh * offset + weight)
    Z = np.zeros((3, 3))
    if mode == PlantMode.FULL:
        Mq = np.block([[Mm * eye, Z], [Z, Mout]])
        Kq = np.block([[k * eye, -k * eye], [-k * eye, k * eye + Khand]])
        Kspring = np.block([[k * eye, -k * eye], [-k * eye, k * eye]])
        Cq = np.block([[xi * eye, Z], [Z, Chand]])
        Bu_q = np.vstack([eta * eye, Z])
        Bl_q = np.vstack([Z, eye])
        out_rows = slice(3, 6)
        bias_q = np.concatenate([np.zeros(3), bias_out])
    elif mode == PlantMode.LOCKED:
        Mq, Kq, Kspring, Cq = Mm * eye, k * eye, k * eye, xi * eye
        Bu_q, Bl_q, out_rows, bias_q = eta * eye, Z, None, np.zeros(3)
    else:
        rigid = mode == PlantMode.RIGID
        Mq = Mout + (Mm * eye if rigid else Z)
        Kq, Kspring = Khand, Z
        Cq = Chand + (xi * eye if rigid else Z)
        Bu_q = eta * eye if rigid else eye
        Bl_q, out_rows, bias_q = eye, slice(0, 3), bias_out
    nq = Mq.shape[0]
    Minv = np.linalg.inv(Mq)
    n = 2 * nq + (6 if op else 0)
    A = np.zeros((n, n))
    A[:nq, nq:2 * nq] = np.eye(nq)
    A[nq:2 * nq, :nq] = -Minv @ Kq
    A[nq:2 * nq, nq:2 * nq] = -Minv @ Cq
    Bu = np.zeros((n, 3))
    Bu[nq:2 * nq] = Minv @ Bu_q
    Bl = np.zeros((n, 3))
    Bl[nq:2 * nq] = Minv @ Bl_q
    c = np.zeros(n)
    c[nq:2 * nq] = Minv @ bias_q
    ref_pos = ref_vel = None
    if op:
        ref_pos, ref_vel = slice(2 * nq, 2 * nq + 3), slice(2 * nq + 3, 2 * nq + 6)
        w = 2.0 * math.pi * scene.motion.frequency
        A[ref_pos, ref_vel] = eye
        A[ref_vel, ref_pos] = -(w**2) * eye
        # hand spring/damper pull the output towards x_r = o + y: Jᵀ k_h y + Jᵀ b_h ẏ in slider space
        coupling = np.zeros((nq, 3))
        coupling[out_rows] = J.T * kh
        A[nq:2 * nq, ref_pos] = Minv @ coupling
        coupling[out_rows] = J.T * bh
        A[nq:2 * nq, ref_vel] = Minv @ coupling
    Q = np.zeros((n, n))
    Q[:nq, :nq] = Kspring
    Q[nq:2 * nq, nq:2 * nq] = Mq
    x0 = np.zeros(n)
    p0 = np.asarray(scene.initial_offset)
    out_pos = out_rows
    out_vel = slice(out_rows.start + nq, out_rows.stop + nq) if out_rows is not None else None
    if out_pos is not None:
        x0[out_pos] = np.linalg.solve(J, p0)
    motor_pos = slice(0, 3) if mode in (PlantMode.FULL, PlantMode.LOCKED) else None
    if mode == PlantMode.FULL:
        x0[motor_pos] = x0[out_pos]  # spring relaxed
    if op:
        amp, ph = np.asarray(scene.motion.amplitude), np.asarray(scene.motion.phase)
        x0[ref_pos] = amp * np.sin(ph)
        x0[ref_vel] = amp * w * np.cos(ph)
    S, limit = friction_coordinates(design, scene.friction_location) if (
        Effect.COULOMB_FRICTION in fx and out_pos is not None) else (None, None)
    on_sliders = S is not None and scene.friction_location != FrictionLocation.R_JOINTS
    return LumpedModel(
        mode=mode, A=A, Bu=Bu, Bl=Bl, c=c, Q=Q, x0=x0, out_pos=out_pos, out_vel=out_vel, motor_pos=motor_pos,
        ref_pos=ref_pos, ref_vel=ref_vel, J=J, spring=k, motor_mass=Mm, viscous=xi, efficiency=eta,
        hand_stiffness=kh, hand_damping=bh, hand_mass=mh, offset=offset,
        coulomb=a.coulomb_friction if on_sliders else 0.0, friction_map=S, friction_limit=limit,
    )


def r_joint_rates(design: PrrrDesign) -> np.ndarray:
    """(9, 3) ∂θ/∂p of the nine R joints at the home pose [rad/m] (the CAD's elbow branch).

    Constant over a run: the scenes move ≤ 4 mm about home, where ∂θ/∂p changes by ≤ 6 %
    (``tests/analysis/prrr/loop/test_lumped_plant.py``); the 3-PRRR's Jacobian J is constant, its
    joint-rate map is not.
    """
    H = joint_rate_jacobian(params_of(design), np.zeros(3), DEFAULT_BRANCH)
    return np.asarray(H).reshape(9, 3)


def friction_coordinates(design: PrrrDesign, location: FrictionLocation) -> tuple[np.ndarray, np.ndarray]:
    """(S (m, 3), limits (m,)): friction-coordinate rates w = S Ḋ_e and their Coulomb limits.

    Sliders: w = Ḋ_e, |μ| ≤ F_c (``actuator.coulomb_friction_N``). R joints: w = θ̇ = H J Ḋ_e with
    H = ∂θ/∂p of each leg's inverse kinematics (:func:`r_joint_rates`), |μ| ≤ τ_c
    (``structure.joint_friction_Nm``); the slider-space force is Sᵀμ (virtual work). H has a zero
    z column, so R-joint friction never acts along z.
    """
    a, s = design.actuator, design.structure
    parts_S, parts_l = [], []
    if location in (FrictionLocation.SLIDERS, FrictionLocation.BOTH):
        parts_S.append(np.eye(3))
        parts_l.append(np.full(3, a.coulomb_friction))
    if location in (FrictionLocation.R_JOINTS, FrictionLocation.BOTH):
        J = jacobian(design.geometry.beta, xp=np)
        parts_S.append(r_joint_rates(design) @ J)
        parts_l.append(np.full(9, s.joint_friction))
    return np.vstack(parts_S), np.concatenate(parts_l)


@dataclass(frozen=True, kw_only=True)
class Discrete:
    """Exact zero-order-hold discretisation over one substep h: x⁺ = Ad x + Bud u + Bld λ + cd."""

    h: float
    Ad: np.ndarray
    Bud: np.ndarray
    Bld: np.ndarray
    cd: np.ndarray


def discretise(model: LumpedModel, h: float) -> Discrete:
    """Matrix exponential of the augmented matrix [[A, B_u, B_λ, c], [0]] over ``h`` [s]."""
    n = model.n
    aug = np.zeros((n + 7, n + 7))
    aug[:n, :n] = model.A
    aug[:n, n:n + 3] = model.Bu
    aug[:n, n + 3:n + 6] = model.Bl
    aug[:n, n + 6] = model.c
    E = scipy.linalg.expm(aug * h)
    return Discrete(h=h, Ad=E[:n, :n], Bud=E[:n, n:n + 3], Bld=E[:n, n + 3:n + 6], cd=E[:n, n + 6])


def solve_friction(xp, v_free, G, limit, lam0, iters: int, *, divide: bool = False):
    """Box LCP of Coulomb friction, vectorised over leading axes (numpy or jax.numpy as ``xp``).

    Find λ ∈ [−F_c, F_c]ᵐ with v = v_free + λ Gᵀ such that λ_i = −F_c·sign(v_i) where v_i ≠ 0
    (maximum dissipation). ``G`` (m, m) maps friction forces to end-of-substep friction-coordinate
    velocities (symmetric positive semi-definite: S M⁻¹ Sᵀ h; singular for the nine R joints of a
    3-DOF platform, where the QP's velocities are still unique). ``limit``: a scalar or (m,).
    Projected Gauss–Seidel from ``lam0``. ``G`` and ``limit`` may be traced arguments of a compiled
    loop (``limit`` then of shape (m,)); ``divide``: a traced ``G`` still divides by G_ii as the
    constant path does (bit-for-bit), instead of multiplying by reciprocals read once.
    """
    m = G.shape[0]
    if isinstance(limit, (np.ndarray, float, int)):
        lim = [float(x) for x in np.broadcast_to(np.asarray(limit, dtype=float), (m,))]
    else:  # a traced (m,) argument
        lim = [limit[i] for i in range(m)]
    if isinstance(G, np.ndarray):  # constants: divide (bit-for-bit the reference path)
        step = [lambda vi, i=i: vi / G[i, i] for i in range(m)]
    elif divide:  # a traced G, divided like the constants
        G = _Entries([[G[i, j] for j in range(m)] for i in range(m)])
        step = [lambda vi, i=i: vi / G[i, i] for i in range(m)]
    else:  # a traced G (the period-free loop): read its entries and reciprocals once, outside the sweeps
        G = _Entries([[G[i, j] for j in range(m)] for i in range(m)])
        inv = [1.0 / G[i, i] for i in range(m)]
        step = [lambda vi, i=i: vi * inv[i] for i in range(m)]

    def sweep(lam, v):
        lam, v = list(lam), list(v)
        for i in range(m):
            new = xp.minimum(xp.maximum(lam[i] - step[i](v[i]), -lim[i]), lim[i])
            d = new - lam[i]
            v = [v[j] + G[j, i] * d for j in range(m)]
            lam[i] = new
        return tuple(lam), tuple(v)

    lam = tuple(lam0[..., i] for i in range(m))
    v = tuple(v_free[..., i] + sum(G[i, j] * lam[j] for j in range(m)) for i in range(m))
    if xp is np:
        for _ in range(iters):
            lam, v = sweep(lam, v)
    else:  # a rolled loop: small compiled code (and it avoids an XLA CPU fusion hang seen with unrolling)
        from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
        import jax

        lam, v = jax.lax.fori_loop(0, iters, lambda _, c: sweep(*c), (lam, v))
    return xp.stack(lam, axis=-1)


FRICTION_ITERS = 12


class _Entries:
    """``G[i, j]`` over a nested list of (traced) scalars."""

    def __init__(self, rows) -> None:
        self.rows = rows
        self.shape = (len(rows), len(rows))

    def __getitem__(self, ij):
        return self.rows[ij[0]][ij[1]]


def sensor_values(model: LumpedModel, x: np.ndarray, u: np.ndarray, xp=np):
    """(slider positions, spring deflections) [m] for states ``x`` (..., n); ``u`` last commands (..., 3)."""
    zeros = xp.zeros(x.shape[:-1] + (3,))
    slider = x[..., model.out_pos] if model.out_pos is not None else zeros
    if model.mode == PlantMode.FULL:
        defl = x[..., model.motor_pos] - x[..., model.out_pos]
    elif model.mode == PlantMode.LOCKED:
        defl = x[..., model.motor_pos]
    elif model.mode == PlantMode.IDEAL:
        defl = u / model.spring  # the spring carries exactly the commanded force
    else:
        defl = zeros
    return slider, defl


def observables(model: LumpedModel, x, u, lam, xp=np):
    """p, ṗ, hand force, Cartesian actuator force (..., 3) and energy (...) at states ``x``."""
    J = model.J
    zeros = xp.zeros(x.shape[:-1] + (3,))
    xdot = x @ model.A.T + u @ model.Bu.T + lam @ model.Bl.T + model.c
    if model.out_pos is None:
        p = v = acc = zeros
    else:
        p = x[..., model.out_pos] @ J.T
        v = x[..., model.out_vel] @ J.T
        acc = xdot[..., model.out_vel] @ J.T
    if model.ref_pos is not None:
        hand = (model.hand_stiffness * (model.offset + x[..., model.ref_pos] - p)
                + model.hand_damping * (x[..., model.ref_vel] - v) - model.hand_mass * acc)
    else:
        hand = zeros
    JinvT = np.linalg.inv(J).T
    if model.mode in (PlantMode.FULL, PlantMode.LOCKED):
        slider, defl = sensor_values(model, x, u, xp)
        f = model.spring * defl
    elif model.mode == PlantMode.IDEAL:
        f = u
    else:  # rigid: force the transmission delivers to the output = ηF − ξḊ − M_m D̈
        f = (model.efficiency * u - model.viscous * x[..., model.out_vel]
             - model.motor_mass * xdot[..., model.out_vel])
    energy = 0.5 * xp.einsum("...i,ij,...j->...", x, model.Q, x)
    return p, v, hand, f @ JinvT.T, energy
