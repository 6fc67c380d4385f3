"""Transparency of the surgical master rendering a virtual spring: G_T(jω) = F_H/F_D and its bandwidth.

Seed 003 eq 13–15: G_T = F_H/F_D with the hand's velocity equal to the ideal one, per axis
(x and z); the transparency bandwidth is the first frequency where |G_T| leaves 0 ± 3 dB.

Model (linearised about a pose q0; the hand imposes δx = e·X·sin ωt along the axis e):
the motors render F_D = −K δx, sampled and held at the firmware period T (zero-order hold
H(jω) = e^{−jωT/2}·sinc(ωT/2) on the fundamental). The arm obeys M q̈ + B q̇ + f_c + G(q) = τ + Jᵀ F_hand.
The controller (seed 003, "model-based feedback compensation without gravity") adds the torque
M̂(q) q̂̈ + Ĉ(q, q̂̇) q̂̇ of a *compensation model* M̂, with q̂̈ the firmware's estimate of the joint
acceleration from its encoder samples (two first-order filtered backward differences at the
firmware's velocity filter, :mod:`hapticopt.analysis.master.firmware`), held like every command. So
the force the hand feels along e is, with q̇ = J⁻¹ẋ, q̈ ≈ J⁻¹ẍ (Coriolis terms are second order):

    G_T(jω) = [K·H + k_g + jω b + j c_f − ω² (λ − λ̂·H·E(jω))] / K,

λ = (J⁻¹e)ᵀ M (J⁻¹e) the apparent mass [kg] and λ̂ that of the compensation model, E(jω) the
acceleration estimator's response divided by (jω)² (→ 1 at low frequency), b = (J⁻¹e)ᵀ B (J⁻¹e)
[N·s/m], k_g = e·∂(J⁻ᵀG)/∂x·e the gravity stiffness [N/m] (the constant gravity force is not part
of the oscillation), c_f = (4/π) Σ_j F_c,j |(J⁻¹e)_j| / X the describing function of Coulomb
friction [N] at the amplitude X. Gravity or friction compensation (off in seed 003) multiplies
those terms by (1 − H).

Compensation models (:class:`hapticopt.analysis.loop.scene.DynamicsCompensation`): ``none`` (open-loop
rendering, λ̂ = 0), ``links`` (the nominal links without the counterweights: seed 003's reading,
the default; docs/master.md says why) and ``full`` (every body).

Closed form (no compensation, no friction, no gravity, T → 0, point mass m): G_T = 1 − m ω²/K,
which leaves −3 dB at ω = √((1 − 1/√2) K/m) (see tests/analysis/master/test_transparency.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hapticopt.analysis.master import dynamics as md
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.loop.scene import DynamicsCompensation
from hapticopt.analysis import conditioning
from hapticopt.analysis.status import Status
from hapticopt.design.master.params import MasterDesign
from hapticopt.analysis.master import dynamics_numpy as mn
from hapticopt.analysis.master import balance as mb

SPRING_N_PER_M = 50.0  # 0.05 N/mm, seed 003's ideal force
AMPLITUDE_M = 7.5e-3  # 7.5 mm, seed 003's hand motion
HOLD_PERIOD_S = 1e-3  # 1 kHz firmware
ESTIMATOR_FILTER_HZ = 100.0  # the firmware's velocity (and acceleration) filter, scenes' velocity_filter_Hz
AXES = ("x", "z")
NEAR_AXIS = 0.2  # worst case: poses with the handle closer than 0.2·L5 to the θ1 axis are left out
F_MIN_HZ, F_MAX_HZ = 1e-3, 500.0
#: worst case over the workspace per fidelity (none at draft): grid (n θ1, n θ3, n φ), then zoom
#: levels around each axis's minimum with this many points per coordinate
WORST_GRID = {Fidelity.STANDARD: (3, 15, 15, 5, 3), Fidelity.FINE: (5, 15, 15, 8, 5)}
_DB3 = np.sqrt(2.0)  # ±3 dB read as half/double power: |G_T| = 1/√2 … √2 (as the closed form)


@dataclass(frozen=True, kw_only=True)
class Compensation:
    """Which model-based torques the controller adds to τ = Jᵀ F_D (seed 003: the links' dynamics, no gravity)."""

    gravity: bool = False
    friction: bool = False
    inertia: DynamicsCompensation = DynamicsCompensation.NONE


#: seed 003's controller: model-based compensation of the links' dynamics, no gravity compensation
PAPER_COMPENSATION = Compensation(inertia=DynamicsCompensation.LINKS)
#: open-loop impedance rendering τ = Jᵀ F_D
OPEN_LOOP = Compensation()


@dataclass(frozen=True, kw_only=True)
class RenderingSetup:
    """Virtual spring and controller of the transparency test [SI].

    The defaults are seed 003's protocol: 0.05 N/mm spring, 7.5 mm amplitude, the links' dynamics
    compensated from the exact (co-simulated) state, no gravity compensation. The 1 kHz
    firmware with encoder differences is ``hold_period=HOLD_PERIOD_S, estimator_filter=ESTIMATOR_FILTER_HZ``.
    """

    spring: float = SPRING_N_PER_M  # K [N/m]
    amplitude: float = AMPLITUDE_M  # X [m], for the Coulomb describing function
    hold_period: float = 0.0  # T [s]; 0 = continuous (seed 003's co-simulation); HOLD_PERIOD_S = the 1 kHz firmware
    compensation: Compensation = PAPER_COMPENSATION
    estimator_filter: float = 0.0  # [Hz] first-order filter of each estimated derivative; 0 = none (exact state)


@dataclass(frozen=True, kw_only=True)
class AxisCoefficients:
    """Linearised apparent dynamics along each axis, arrays (…, 2 axes) [SI]."""

    mass: np.ndarray  # λ [kg]
    compensated_mass: np.ndarray  # λ̂ [kg] of the compensation model (…, 2, 3 models: none, links, full)
    damping: np.ndarray  # b [N·s/m]
    gravity_stiffness: np.ndarray  # k_g [N/m]
    coulomb: np.ndarray  # (4/π)·Σ F_c |v_j| / X [N]
    valid: np.ndarray  # bool: J invertible at the pose


def default_pose(design: MasterDesign) -> np.ndarray:
    """The pose at the middle of the θ3 and φ ranges with θ1 = 0 [rad]."""
    j = design.joints
    t3 = 0.5 * (j.theta3_min + j.theta3_max)
    ph = 0.5 * (j.parallelogram_min + j.parallelogram_max)
    return np.array([0.5 * (j.theta1_min + j.theta1_max), 0.5 * np.pi + t3 - ph, t3])


def axis_coefficients(model: md.MassModel, q: np.ndarray, amplitude: float = AMPLITUDE_M, *,
                      gravity: md.GravityParameters | None = None) -> AxisCoefficients:
    """Apparent mass, damping, gravity stiffness and Coulomb term along x and z at poses q (…, 3).

    NumPy fast path (:mod:`hapticopt.analysis.master.dynamics_numpy`); the gravity stiffness is the central
    difference of J⁻ᵀG along δq = h·J⁻¹e (h = 1e-5 m, error ~1e-10 relative), with G in the
    eq-4 form whose coefficients come from the general G (:func:`md.gravity_parameters`;
    the tests check the form against the general ∂V/∂q).
    """

    q = np.asarray(q, dtype=float)
    flat = q.reshape(-1, 3)
    E = np.eye(3)[[0, 2]].T  # (3, 2): x and z
    J = mn.jacobian(model.kin, flat)
    # verdict from the reciprocal condition number of J (columns scaled by the upper-arm length,
    # so m/rad become dimensionless): singular and ill-conditioned poses (rcond < RCOND_ILL) are
    # not valid, never a solve of a near-singular matrix (analysis.conditioning)
    sv = np.linalg.svd(J / float(model.kin.upper_arm), compute_uv=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        rc = np.where(sv[:, 0] > 0.0, sv[:, -1] / sv[:, 0], 0.0)
    valid = np.isfinite(rc) & (rc >= conditioning.RCOND_ILL)
    Jsafe = np.where(valid[:, None, None], J, np.eye(3))
    V = np.linalg.solve(Jsafe, np.broadcast_to(E, Jsafe.shape[:-2] + (3, 2)))  # (n, 3, 2)
    Mb = mn.body_mass_matrices(model, flat)  # (n, nb, 3, 3)
    rotor = np.diag(np.asarray(model.rotor_inertia))
    cw = np.asarray(model.counterweight, dtype=float)
    M = Mb.sum(axis=1) + rotor
    M_links = np.einsum("b,nbij->nij", 1.0 - cw, Mb) + rotor
    lam = np.einsum("nja,njk,nka->na", V, M, V)
    lam_links = np.einsum("nja,njk,nka->na", V, M_links, V)
    lam_c = np.stack([np.zeros_like(lam), lam_links, lam], -1)  # order of _MODELS
    b = np.einsum("nja,j,nja->na", V, np.asarray(model.viscous), V)
    cf = (4.0 / np.pi) * np.einsum("j,nja->na", np.asarray(model.coulomb), np.abs(V)) / amplitude

    gp = md.gravity_parameters(model) if gravity is None else gravity

    def gravity_force(qq: np.ndarray) -> np.ndarray:
        Jq = mn.jacobian(model.kin, qq)
        G = np.stack([np.zeros(len(qq)), gp.G1 * np.cos(qq[:, 1]), gp.G2 * np.sin(qq[:, 2])], -1)
        return np.linalg.solve(np.swapaxes(Jq, -1, -2), G[..., None])[..., 0]

    h = 1e-5
    kg = np.zeros_like(lam)
    for a in range(2):  # only at valid poses: no solve near a singularity
        dq = h * V[valid, :, a]
        dF = (gravity_force(flat[valid] + dq) - gravity_force(flat[valid] - dq)) / (2 * h)
        kg[valid, a] = dF @ E[:, a]  # k_g = e·∂(J⁻ᵀG)/∂x·e (enters G_T with a + sign, module docstring)
    shape = q.shape[:-1] + (2,)
    clean = lambda x: np.where(valid[:, None], x, np.nan).reshape(shape)  # noqa: E731  (NaN: not a number to use)
    lam_c = np.where(valid[:, None, None], lam_c, np.nan).reshape(shape + (3,))
    return AxisCoefficients(mass=clean(lam), compensated_mass=lam_c, damping=clean(b),
                            gravity_stiffness=clean(kg), coulomb=clean(cf), valid=valid.reshape(shape[:-1]))


def hold(omega: np.ndarray, period: float) -> np.ndarray:
    """Zero-order hold on the fundamental: e^{−jωT/2}·sinc(ωT/2) (1 at T = 0)."""
    x = 0.5 * omega * period
    return np.exp(-1j * x) * np.sinc(x / np.pi)


_MODELS = (DynamicsCompensation.NONE, DynamicsCompensation.LINKS, DynamicsCompensation.FULL)


def estimator(omega: np.ndarray, period: float, cutoff: float) -> np.ndarray:
    """E(jω): the firmware's acceleration estimate over the true acceleration (−ω²·x), on the fundamental.

    Two cascaded filtered backward differences D(z) = (1 − a)(1 − z⁻¹) / (T (1 − a z⁻¹)),
    a = e^{−2π f_c T} (a = 0 without filter), at z = e^{jωT}: E = D² / (jω)². Continuous
    (T = 0): first-order low-passes 1/(1 + jω/ω_c)².
    """
    w = np.asarray(omega, dtype=float)
    if period <= 0.0:
        return np.ones_like(w, dtype=complex) if cutoff <= 0 else 1.0 / (1.0 + 1j * w / (2 * np.pi * cutoff)) ** 2
    a = np.exp(-2 * np.pi * cutoff * period) if cutoff > 0 else 0.0
    zi = np.exp(-1j * w * period)
    D = (1.0 - a) * (1.0 - zi) / (period * (1.0 - a * zi))
    jw = np.where(w > 0, 1j * w, 1j)
    return np.where(w > 0, (D / jw) ** 2, 1.0)


def _response(coef: AxisCoefficients, w: np.ndarray, setup: RenderingSetup, entry_shaped: bool) -> np.ndarray:
    """G_T(jω); w broadcast against the entries (entry_shaped) or appended as the last axis."""
    H = hold(w, setup.hold_period)
    E = estimator(w, setup.hold_period, setup.estimator_filter)
    c = setup.compensation
    keep = lambda comp: (1.0 - H) if comp else 1.0  # noqa: E731
    pick = lambda x: x if entry_shaped else x[..., None]  # noqa: E731
    lam, b, kg, cf = (pick(x) for x in (coef.mass, coef.damping, coef.gravity_stiffness, coef.coulomb))
    lam_c = pick(coef.compensated_mass[..., _MODELS.index(c.inertia)])
    num = (setup.spring * H + kg * keep(c.gravity) + (1j * w * b + 1j * cf) * keep(c.friction)
           - w**2 * (lam - lam_c * H * E))
    return num / setup.spring


def transfer(coef: AxisCoefficients, freq_hz: np.ndarray, setup: RenderingSetup = RenderingSetup()) -> np.ndarray:
    """G_T(j2πf) for every coefficient entry (…) and frequency (f,) → (…, f) complex."""
    return _response(coef, 2 * np.pi * np.asarray(freq_hz, dtype=float), setup, entry_shaped=False)


def bandwidth(coef: AxisCoefficients, setup: RenderingSetup = RenderingSetup(), *, n_grid: int = 120,
              iterations: int = 14) -> tuple[np.ndarray, np.ndarray]:
    """First frequency [Hz] where |G_T| leaves [−3 dB, +3 dB], per entry; and a flag 'left at DC'.

    Log grid from F_MIN_HZ to F_MAX_HZ, then bisection in log f on the first bracketing cell and
    a final linear interpolation of log|G_T| in the last bracket (relative error < 1e-9).
    Entries that never leave the band below F_MAX_HZ get F_MAX_HZ; entries already outside at
    F_MIN_HZ get 0.
    """
    f = np.geomspace(F_MIN_HZ, F_MAX_HZ, n_grid)
    G = np.abs(transfer(coef, f, setup))  # (…, n)
    o = (G > _DB3) | (G < 1.0 / _DB3)
    first = np.argmax(o, axis=-1)
    never = ~o.any(axis=-1)
    at_dc = o[..., 0]
    lo = np.log(f[np.maximum(first - 1, 0)])
    hi = np.log(f[first])
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        om = _outside_pointwise(coef, np.exp(mid), setup)
        hi = np.where(om, mid, hi)
        lo = np.where(om, lo, mid)
    # last bracket: interpolate log|G_T| linearly onto the bound it crosses
    g_lo = np.log(np.abs(_pointwise(coef, np.exp(lo), setup)))
    g_hi = np.log(np.abs(_pointwise(coef, np.exp(hi), setup)))
    bound = np.where(g_hi > 0, np.log(_DB3), -np.log(_DB3))
    span = np.where(np.abs(g_hi - g_lo) > 0, g_hi - g_lo, 1.0)
    s = np.clip((bound - g_lo) / span, 0.0, 1.0)
    bw = np.exp(lo + s * (hi - lo))
    bw = np.where(never, F_MAX_HZ, np.where(at_dc, 0.0, bw))
    return bw, at_dc


def _outside(G: np.ndarray) -> np.ndarray:
    m = np.abs(G)
    return (m > _DB3) | (m < 1.0 / _DB3)


def _outside_pointwise(coef: AxisCoefficients, f: np.ndarray, setup: RenderingSetup) -> np.ndarray:
    return _outside(_pointwise(coef, f, setup))


def _pointwise(coef: AxisCoefficients, f: np.ndarray, setup: RenderingSetup) -> np.ndarray:
    """G_T at one frequency per entry (f has the entries' shape)."""
    return _response(coef, 2 * np.pi * f, setup, entry_shaped=True)


@dataclass(frozen=True, kw_only=True)
class MasterTransparency:
    """Transparency bandwidth of one design [SI]."""

    pose: tuple[float, float, float]  # q [rad]
    bandwidth: tuple[float, float]  # [Hz] x, z at the pose
    apparent_mass: tuple[float, float]  # λ [kg] x, z at the pose
    gravity_stiffness: tuple[float, float]  # [N/m]
    worst_bandwidth: tuple[float, float] | None  # [Hz] min over the workspace (standard, fine fidelity)
    worst_pose: tuple[tuple[float, float, float], tuple[float, float, float]] | None
    setup: RenderingSetup
    coefficients: AxisCoefficients = field(repr=False)
    status: Status = Status.OK
    message: str = ""

    def metrics(self) -> dict[str, object]:
        out: dict[str, object] = {
            "transparency_bandwidth_Hz": [float(x) for x in self.bandwidth],
            "transparency_bandwidth_min_Hz": float(min(self.bandwidth)),
            "apparent_mass_kg": [float(x) for x in self.apparent_mass],
        }
        if self.worst_bandwidth is not None:
            out["transparency_bandwidth_worst_Hz"] = [float(x) for x in self.worst_bandwidth]
        return out


def evaluate(design: MasterDesign, *, fidelity: Fidelity = Fidelity.STANDARD, setup: RenderingSetup = RenderingSetup(),
             pose: np.ndarray | None = None, model: md.MassModel | None = None) -> MasterTransparency:
    """Transparency bandwidth along x and z at ``pose`` (default :func:`default_pose`); at standard
    and fine fidelity also the worst case over a grid of the joint-range workspace (:data:`WORST_GRID`)."""

    fidelity = Fidelity(fidelity)
    model = md.model_of(design) if model is None else model
    q0 = default_pose(design) if pose is None else np.asarray(pose, dtype=float)
    gp = md.gravity_parameters(model)
    coef = axis_coefficients(model, q0[None], setup.amplitude, gravity=gp)
    status, message = Status.OK, ""
    if not bool(coef.valid[0]):
        nan2 = (float("nan"), float("nan"))
        verdict = conditioning.classify(mn.jacobian(model.kin, q0[None])[0] / float(model.kin.upper_arm),
                                        what="J at the pose (cos(θ2 − θ3) ≈ 0 or the handle on the θ1 axis)")
        return MasterTransparency(pose=tuple(map(float, q0)), bandwidth=nan2, apparent_mass=nan2,
                                  gravity_stiffness=nan2, worst_bandwidth=None, worst_pose=None, setup=setup,
                                  coefficients=coef, status=verdict.status if not verdict.ok else Status.SINGULAR,
                                  message=verdict.message or "J at the pose is not finite")
    bw, dc = bandwidth(coef, setup)
    if dc.any():
        status, message = Status.UNSTABLE, "|G_T| is outside ±3 dB already at DC (gravity stiffness too large)"
        bw = np.full_like(bw, np.nan)  # no bandwidth to report
    worst = worst_pose = None
    if fidelity in WORST_GRID:
        n1, n3, nph, levels, zoom_points = WORST_GRID[fidelity]
        ws = mb.workspace_of(design)
        j = design.joints
        lo = np.array([j.theta1_min, ws.theta3[0], ws.phi[0]])
        hi = np.array([j.theta1_max, ws.theta3[1], ws.phi[1]])
        g = design.geometry

        def bandwidths(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            """(θ1, θ3, φ) points → poses kept (away from the θ1 axis) and their bandwidths (n, 2)."""
            Q = np.stack([P[:, 0], 0.5 * np.pi + P[:, 1] - P[:, 2], P[:, 1]], -1)
            rho = g.upper_arm * np.cos(Q[:, 1]) + g.forearm * np.sin(Q[:, 2])
            Q = Q[rho >= NEAR_AXIS * g.upper_arm]  # near the θ1 axis the turret's apparent mass diverges
            cw = axis_coefficients(model, Q, setup.amplitude, gravity=gp)
            bws, _ = bandwidth(cw, setup)
            return Q, np.where(cw.valid[:, None], bws, np.inf)

        axes_ = [np.linspace(lo[i], hi[i], n) for i, n in enumerate((n1, n3, nph))]
        P0 = np.stack(np.meshgrid(*axes_, indexing="ij"), -1).reshape(-1, 3)
        Q, bws = bandwidths(P0)
        step = (hi - lo) / np.maximum(np.array([n1, n3, nph]) - 1, 1)
        worst_l, pose_l = [], []
        for a in range(2):  # zoom around each axis's grid minimum (as the unbalance maximisation)
            k = int(np.argmin(bws[:, a]))
            best_v, best_q = float(bws[k, a]), Q[k]
            h = step.copy()
            for _ in range(levels):
                c = np.array([best_q[0], best_q[2], 0.5 * np.pi + best_q[2] - best_q[1]])  # (θ1, θ3, φ)
                loc = [np.clip(np.linspace(c[i] - h[i], c[i] + h[i], zoom_points), lo[i], hi[i]) for i in range(3)]
                Qz, bz = bandwidths(np.stack(np.meshgrid(*loc, indexing="ij"), -1).reshape(-1, 3))
                if len(Qz) and float(bz[:, a].min()) < best_v:
                    kz = int(np.argmin(bz[:, a]))
                    best_v, best_q = float(bz[kz, a]), Qz[kz]
                h = 0.5 * h
            worst_l.append(best_v)
            pose_l.append(tuple(map(float, best_q)))
        worst = (worst_l[0], worst_l[1])
        worst_pose = (pose_l[0], pose_l[1])
        if ws.clipped:
            status = Status.SINGULAR
            message = "the φ range reaches the parallelogram singularity: poses within 2° of it are excluded"
    return MasterTransparency(
        pose=tuple(map(float, q0)), bandwidth=(float(bw[0, 0]), float(bw[0, 1])),
        apparent_mass=(float(coef.mass[0, 0]), float(coef.mass[0, 1])),
        gravity_stiffness=(float(coef.gravity_stiffness[0, 0]), float(coef.gravity_stiffness[0, 1])),
        worst_bandwidth=worst, worst_pose=worst_pose, setup=setup, coefficients=coef, status=status, message=message)
