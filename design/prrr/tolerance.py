"""The 3-PRRR as manufactured: per-leg geometric errors, off-nominal kinematics, Jacobian constancy.

Nominal leg (``kinematics.py``, seed digest 002): a rail along e_z, R1, R2, R3 with parallel axes w,
p = Q + b5 w − r5 e_z. As built, every leg i has its own errors (:data:`ERRORS`, SI: metres and
radians, shape ``(..., 3 legs, N_ERRORS)``, zero = nominal):

* rail: direction tilted towards u and t (``rail_tilt_u``, ``rail_tilt_t``, pivot at z = 0), its
  position moved radially and tangentially about its nominal place (``rail_radial``,
  ``rail_tangential``, along e_rail = cos θ_1p u + sin θ_1p t and e_z × e_rail);
* lengths ``d1`` (along u), ``d2`` (along t), ``d3`` (R1–R2 along v), ``d4`` (R2–R3 along v), ``r4``
  (along w), ``b5`` (along w), ``r5`` (along e_z: the platform's pin offset);
* axis directions tilted towards v and t: R1 (``r1_tilt_v``, ``r1_tilt_t``, in the carriage), R2 (in
  link 1), R3's bore in link 2 (``r3_tilt_*``) and R3's bore in the platform (``rp_tilt_*``).

Chain (product of exponentials about the zero configuration θ = 0, where link 1 points along v):
A = A0 + D a, B = A + Rot(w1, θ1)(d3 v), Q = A + Rot(w1, θ1)[d3 v + Rot(w2, θ2)(d4 v + r4 w)];
the R3 axis carried by link 2 is n = Rot(w1, θ1) Rot(w2, θ2) w3. With zero errors this is the
nominal leg exactly (Rot(w, θ) v = cos θ v + sin θ t = e(θ)).

**The overconstraint.** The nominal 3-PRRR is overconstrained (Grübler gives 0 DOF; the parallel axes
make it 3): with axis errors the rigid chains cannot assemble. The model closes each leg's R3 pin
point exactly on the platform, Q_i = p + c_i + φ × c_i (c_i = −b5 w + r5 e_z, the pin's offset from
the end-effector centre; φ the platform's small rotation vector, rotation to first order: an
O(|φ|²·|c|) approximation, < 0.1 µm at 1 mrad), and takes the platform's rotation from equal angular
compliance of the three R3 joints: φ minimises Σ_i |n_i − (wp_i + φ × wp_i)|² (wp_i: the platform's
bore direction), i.e. (3I − Σ wp_i wp_iᵀ) φ = Σ wp_i × n_i. Then the device has 3 DOF again: 12
equations in (p, D, θ1, θ2, φ) (15 unknowns). IK (p given) and FK (D given) solve the same equations
by Newton from the nominal solution, so FK ∘ IK closes to round-off. The residual angles
|n_i − R wp_i| are the misfit the joints' clearance or the links' compliance must take.

J(p) = dp/dD off nominal by the implicit function theorem on the same equations. Batch-first
numpy: any leading shape of devices and poses (errors ``(N, 3, N_ERRORS)`` against poses ``(P, 3)``
give ``(N, P, …)``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from hapticopt.design.prrr import kinematics as kin
from hapticopt.design.prrr.params import PrrrDesign

#: per-leg error components (SI: m or rad); their order is the last axis of an error array
ERRORS: tuple[str, ...] = (
    "rail_tilt_u", "rail_tilt_t", "rail_radial", "rail_tangential",
    "d1", "d2", "d3", "d4", "r4", "b5", "r5",
    "r1_tilt_v", "r1_tilt_t", "r2_tilt_v", "r2_tilt_t", "r3_tilt_v", "r3_tilt_t", "rp_tilt_v", "rp_tilt_t",
)
N_ERRORS = len(ERRORS)
#: which errors are angles [rad] (the others are lengths [m])
ANGULAR: tuple[bool, ...] = tuple("tilt" in name for name in ERRORS)
_I = {name: k for k, name in enumerate(ERRORS)}
#: elbow branch of every leg: the CAD's (``design/prrr/cad.py`` DEFAULT_BRANCH, θ2 ≤ 0)
BRANCH = 1
#: Newton iterations of IK and FK from the nominal solution (quadratic convergence: 1e-4 m → 1e-8 → 1e-16)
NEWTON_STEPS = 4


def zero_errors(*lead: int) -> np.ndarray:
    """An all-zero error array of leading shape ``lead`` (the nominal device)."""
    return np.zeros((*lead, 3, N_ERRORS))


def error_index(name: str) -> int:
    """Position of the error ``name`` on the last axis."""
    return _I[name]


class Device(NamedTuple):
    """As-built leg vectors, each ``(..., 3 legs, 3)`` [m or unit] (``...``: the devices' batch)."""

    a: np.ndarray  # rail direction
    a0: np.ndarray  # R1 axis point at D = 0
    w1: np.ndarray  # R1 axis (zero configuration)
    w2: np.ndarray  # R2 axis
    w3: np.ndarray  # R3 axis in link 2
    wp: np.ndarray  # R3 bore in the platform
    l1: np.ndarray  # B0 − A0 (link 1)
    l2: np.ndarray  # Q0 − B0 (link 2)
    c: np.ndarray  # pin point Q − p on the platform
    gram: np.ndarray  # (..., 3, 3) 3I − Σ wp wpᵀ (the compliance equation's matrix)


def _cross(a, b, xp=np):
    """a × b over the last axis (component-wise: numpy's ``cross`` moves axes and costs ~3×)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return xp.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _dot(a, b, xp=np):
    """a·b over the last axis (size 3; written out: cheaper than a short-axis reduction)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _matvec(m, x, xp=np):
    """m x for (..., r, k) matrices and (..., k) vectors, k ≤ 3, written out."""
    out = m[..., 0] * x[..., None, 0]
    for c in range(1, m.shape[-1]):
        out = out + m[..., c] * x[..., None, c]
    return out


def _unit(x, xp=np):
    return x / xp.sqrt(_dot(x, x, xp))[..., None]


def _tilt(axis, e1, e2, a1, a2, xp=np):
    """``axis`` tilted by the angles a1 towards e1 and a2 towards e2 (e1, e2 ⊥ axis; ``axis`` at zero)."""
    return _unit(axis + xp.tan(a1)[..., None] * e1 + xp.tan(a2)[..., None] * e2, xp)


def build(design: PrrrDesign, errors, xp=np) -> Device:
    """The as-built device(s) of ``design`` with ``errors`` ``(..., 3, N_ERRORS)`` (``xp``: array module)."""
    errors = xp.asarray(errors, dtype=float)
    g = design.geometry
    f = kin.leg_frames(g.beta, xp=np)
    u, t, v, w = f.u, f.t, f.v, f.w
    ez = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (3, 3))
    e = {name: errors[..., k][..., None] for name, k in _I.items()}  # (..., 3, 1)
    e_rail = np.cos(g.theta_1p) * u + np.sin(g.theta_1p) * t
    t_rail = np.cross(ez, e_rail)
    a0 = (g.d1 * u + g.d2 * t + e["d1"] * u + e["d2"] * t + e["rail_radial"] * e_rail
          + e["rail_tangential"] * t_rail)

    def tilt(axis, e1, e2, name, s1, s2):
        return _tilt(axis, e1, e2, errors[..., _I[f"{name}_{s1}"]], errors[..., _I[f"{name}_{s2}"]], xp)

    a = tilt(ez, u, t, "rail_tilt", "u", "t")
    w1 = tilt(w, v, t, "r1_tilt", "v", "t")
    w2 = tilt(w, v, t, "r2_tilt", "v", "t")
    w3 = tilt(w, v, t, "r3_tilt", "v", "t")
    wp = tilt(w, v, t, "rp_tilt", "v", "t")
    r5 = g.b5 * np.sin(g.beta)
    l1 = (g.d3 + e["d3"]) * v
    l2 = (g.d4 + e["d4"]) * v + (g.r4 + e["r4"]) * w
    c = -(g.b5 + e["b5"]) * w + (r5 + e["r5"]) * ez
    lead = errors.shape[:-2]
    a, a0, w1, w2, w3, wp, l1, l2, c = (xp.broadcast_to(x, (*lead, 3, 3)) for x in (a, a0, w1, w2, w3, wp, l1, l2, c))
    gram = 3.0 * np.eye(3) - xp.sum(wp[..., :, None] * wp[..., None, :], axis=-3)
    return Device(a=a, a0=a0, w1=w1, w2=w2, w3=w3, wp=wp, l1=l1, l2=l2, c=c, gram=gram)


def _rot(k, cs, x, xp=np):
    """Rodrigues: ``x`` turned about the unit axis ``k`` by the angle whose (cos, sin) is ``cs`` (each with a
    trailing axis of 1; broadcast, vectors on the last axis)."""
    c, s = cs
    return x * c + _cross(k, x, xp) * s + k * _dot(k, x, xp)[..., None] * (1.0 - c)


def _cs(th, xp=np):
    return xp.cos(th)[..., None], xp.sin(th)[..., None]


def _expand(dev: Device, ndim_extra: int) -> Device:
    """``dev`` with ``ndim_extra`` axes inserted after its batch axes (for a batch of poses)."""
    def ex(x):
        lead = x.ndim - 2
        return x.reshape(x.shape[:lead] + (1,) * ndim_extra + x.shape[lead:])
    return Device(*(ex(x) for x in dev))


class State(NamedTuple):
    """An assembled configuration, batch-first: p, D ``(..., 3)``, θ ``(..., 3 legs, 2)`` (θ1, θ2),
    φ ``(..., 3)`` [m, m, rad, rad]."""

    p: np.ndarray
    sliders: np.ndarray
    theta: np.ndarray
    phi: np.ndarray


class _Chain(NamedTuple):
    q: np.ndarray  # (..., 3 legs, 3) R3 pin points
    n: np.ndarray  # (..., 3 legs, 3) R3 axes carried by link 2
    dq: np.ndarray  # (..., 3 legs, 3 xyz, 3 cols (D, θ1, θ2)) ∂Q/∂(D, θ1, θ2)
    dhth: np.ndarray  # (..., 3 legs, 3 xyz, 2 cols (θ1, θ2)) ∂H/∂θ = −wp × ∂n/∂θ


def _chain(dev: Device, sliders, theta, xp=np) -> _Chain:
    r1, r2 = _cs(theta[..., 0], xp), _cs(theta[..., 1], xp)
    w2r = _rot(dev.w1, r1, dev.w2, xp)
    b_to_q = _rot(dev.w1, r1, _rot(dev.w2, r2, dev.l2, xp), xp)  # Q − B
    arm = _rot(dev.w1, r1, dev.l1, xp) + b_to_q  # Q − A
    q = dev.a0 + sliders[..., None] * dev.a + arm
    n = _rot(dev.w1, r1, _rot(dev.w2, r2, dev.w3, xp), xp)
    dq = xp.stack([xp.broadcast_to(dev.a, q.shape), _cross(dev.w1, arm, xp), _cross(w2r, b_to_q, xp)], axis=-1)
    dhth = -xp.stack([_cross(dev.wp, _cross(dev.w1, n, xp), xp), _cross(dev.wp, _cross(w2r, n, xp), xp)], axis=-1)
    return _Chain(q=q, n=n, dq=dq, dhth=dhth)


def _residual(dev: Device, st: State, ch: _Chain, xp=np):
    """F (..., 3 legs, 3): pin closure; H (..., 3): the compliance equation."""
    f = ch.q - st.p[..., None, :] - dev.c - _cross(st.phi[..., None, :], dev.c, xp)
    m = _cross(dev.wp, ch.n, xp)
    h = _matvec(dev.gram, st.phi, xp) - (m[..., 0, :] + m[..., 1, :] + m[..., 2, :])
    return f, h


def _skew(x, xp=np):
    z = xp.zeros_like(x[..., 0])
    return xp.stack([xp.stack([z, -x[..., 2], x[..., 1]], -1), xp.stack([x[..., 2], z, -x[..., 0]], -1),
                     xp.stack([-x[..., 1], x[..., 0], z], -1)], -2)


def _inv3(m, xp=np):
    """Inverse of (..., 3, 3) by the adjugate (columns c0, c1, c2: rows of the inverse are c1×c2 …)."""
    c0, c1, c2 = m[..., :, 0], m[..., :, 1], m[..., :, 2]
    rows = xp.stack([_cross(c1, c2, xp), _cross(c2, c0, xp), _cross(c0, c1, xp)], axis=-2)
    return rows / _dot(c0, rows[..., 0, :], xp)[..., None, None]


class _Factor(NamedTuple):
    """The IK Newton matrix by its block structure: per leg K_i x_i + [c_i]× δφ = −F_i (K_i = ∂Q_i/∂(D, θ1,
    θ2)), A δφ + Σ_i Hθ_i δθ_i = −H; eliminating x_i leaves a 3×3 Schur complement in δφ."""

    ki: np.ndarray  # (..., legs, 3, 3) K⁻¹
    kc: np.ndarray  # (..., legs, 3, 3) K⁻¹[c]×
    hth: np.ndarray  # (..., legs, 3, 2)
    schur_inv: np.ndarray  # (..., 3, 3)


def _factor(dev: Device, ch: _Chain, xp=np) -> _Factor:
    ki = _inv3(ch.dq, xp)
    kc = ki @ _skew(dev.c, xp)
    hk = ch.dhth @ kc[..., 1:, :]
    schur = dev.gram - (hk[..., 0, :, :] + hk[..., 1, :, :] + hk[..., 2, :, :])
    return _Factor(ki=ki, kc=kc, hth=ch.dhth, schur_inv=_inv3(schur, xp))


def _apply(fac: _Factor, f, h, xp=np):
    """(δD, δθ, δφ) solving the IK Newton system with residuals F, H."""
    kf = _matvec(fac.ki, f, xp)
    hk = _matvec(fac.hth, kf[..., 1:], xp)
    rhs = -h + hk[..., 0, :] + hk[..., 1, :] + hk[..., 2, :]
    d_phi = _matvec(fac.schur_inv, rhs, xp)
    x = -kf - _matvec(fac.kc, d_phi[..., None, :], xp)
    return x[..., 0], x[..., 1:], d_phi


def _solve_fk(ch: _Chain, dev: Device, f, h):
    """FK Newton step (unknowns p, θ, φ): a dense 12×12 solve (numpy; FK is not on a hot path)."""
    lead = f.shape[:-2]
    m = np.zeros((*lead, 12, 12))
    cskew = _skew(dev.c)
    for i in range(3):
        r = slice(3 * i, 3 * i + 3)
        m[..., r, 0:3] = -np.eye(3)
        m[..., r, 3 + 2 * i:5 + 2 * i] = ch.dq[..., i, :, 1:]
        m[..., r, 9:12] = cskew[..., i, :, :]
        m[..., 9:12, 3 + 2 * i:5 + 2 * i] = ch.dhth[..., i, :, :]
    m[..., 9:12, 9:12] = dev.gram
    rhs = -np.concatenate([f.reshape(*lead, 9), h], axis=-1)
    x = np.linalg.solve(m, rhs[..., None])[..., 0]
    return x[..., 0:3], x[..., 3:9].reshape(*lead, 3, 2), x[..., 9:12]


def _nominal_start(design: PrrrDesign, p, branch: int):
    ik = kin.inverse_kinematics(kin.params_np(design), np.asarray(p), xp=np)
    return np.asarray(ik.sliders), np.asarray(ik.theta)[..., branch, :, :2]


def _ik_newton(dev: Device, st: State, steps: int, xp=np) -> tuple[State, _Chain, _Factor, np.ndarray]:
    """``steps`` Newton steps of IK: the final state, and the chain, factor and largest residual of the
    last iterate (the last step moves a converged state by round-off: a last residual r leaves ~r² after
    it, so J, the R3 axes and the convergence test are taken there)."""
    for _ in range(steps):
        ch = _chain(dev, st.sliders, st.theta, xp)
        f, h = _residual(dev, st, ch, xp)
        fac = _factor(dev, ch, xp)
        d_sl, d_th, d_phi = _apply(fac, f, h, xp)
        st = State(p=st.p, sliders=st.sliders + d_sl, theta=st.theta + d_th, phi=st.phi + d_phi)
    resid = xp.maximum(xp.max(xp.abs(f), axis=(-2, -1)), xp.max(xp.abs(h), axis=-1))
    return st, ch, fac, resid


def _jacobian_from(fac: _Factor, xp=np):
    """J = dp/dD from the IK factor: dD/dp column j solves the system with F_i = −e_j (F = Q − p − …)."""
    lead = fac.schur_inv.shape[:-2]
    cols = []
    for j in range(3):
        f = -xp.broadcast_to(np.eye(3)[j], (*lead, 3, 3))
        d_sl, _, _ = _apply(fac, f, xp.zeros((*lead, 3)), xp)
        cols.append(d_sl)  # dx = −M⁻¹ G_p dp, and G_p is −I on the F rows
    return _inv3(xp.stack(cols, axis=-1), xp)


def _start(design: PrrrDesign, dev: Device, p, branch: int, xp=np) -> tuple[Device, State]:
    p = np.asarray(p, dtype=float)
    sl0, th0 = _nominal_start(design, p, branch)
    shape = (*dev.a.shape[:-2], *p.shape[:-1])
    st = State(p=xp.broadcast_to(p, (*shape, 3)), sliders=xp.broadcast_to(sl0, (*shape, 3)),
               theta=xp.broadcast_to(th0, (*shape, 3, 2)), phi=xp.zeros((*shape, 3)))
    return _expand(dev, p.ndim - 1), st


def inverse_kinematics(design: PrrrDesign, dev: Device, p, *, branch: int = BRANCH,
                       steps: int = NEWTON_STEPS) -> State:
    """Off-nominal IK: the state at end-effector positions ``p`` ``(P, 3)`` (or ``(3,)``) of the devices
    ``dev`` (batch ``(N,)``, or none); result batch ``(N, P)``. Newton from the nominal solution."""
    d, st = _start(design, dev, p, branch)
    return _ik_newton(d, st, steps)[0]


def forward_kinematics(design: PrrrDesign, dev: Device, sliders, *, branch: int = BRANCH,
                       steps: int = NEWTON_STEPS) -> State:
    """Off-nominal FK: the state at slider positions ``sliders`` ``(P, 3)`` of the devices ``dev``.
    Newton from the nominal FK (p = J (D − c_e)) and its nominal IK."""
    sliders = np.asarray(sliders, dtype=float)
    par = kin.params_np(design)
    p0 = (sliders - float(kin.slider_offset(par, xp=np))) @ np.asarray(kin.jacobian(par.beta, xp=np)).T
    d, st = _start(design, dev, p0, branch)
    st = State(p=np.array(st.p), sliders=np.broadcast_to(sliders, st.sliders.shape), theta=np.array(st.theta),
               phi=st.phi)
    for _ in range(steps):
        ch = _chain(d, st.sliders, st.theta)
        f, h = _residual(d, st, ch)
        d_p, d_th, d_phi = _solve_fk(ch, d, f, h)
        st = State(p=st.p + d_p, sliders=st.sliders, theta=st.theta + d_th, phi=st.phi + d_phi)
    return st


def _pose_dev(dev: Device, st: State) -> Device:
    return _expand(dev, st.p.ndim - 1 - (dev.a.ndim - 2))


def jacobian(dev: Device, st: State) -> np.ndarray:
    """J = dp/dD (…, 3, 3) at the assembled states ``st`` (implicit function theorem on the 12 closure
    equations: J⁻¹ = dD/dp from the IK system, then inverted)."""
    d = _pose_dev(dev, st)
    return _jacobian_from(_factor(d, _chain(d, st.sliders, st.theta)))


def pose_grid(diameter: float = 0.140, height: float = 0.089, *, rings: int = 3, per_ring: int = 11,
              levels: int = 3) -> np.ndarray:
    """Poses ``(P, 3)`` [m] over a vertical cylinder about z centred on the home pose: the axis and
    ``rings`` rings of ``per_ring`` points (the outermost on the rim) at ``levels`` heights
    (bottom, …, top). Default 3 × (1 + 3 × 11) = 102 poses over seed 002's φ140 × 89 mm."""
    pts = []
    for z in np.linspace(-height / 2.0, height / 2.0, levels):
        pts.append([0.0, 0.0, z])
        for r in np.linspace(diameter / 2.0 / rings, diameter / 2.0, rings):
            for a in np.arange(per_ring) * 2.0 * np.pi / per_ring:
                pts.append([r * np.cos(a), r * np.sin(a), z])
    return np.asarray(pts)


class Offnominal(NamedTuple):
    """Per device (leading batch shape ``(N,)``): what the errors do over the pose grid."""

    constancy: np.ndarray  # max_p ‖J(p) − J_nom‖_F / ‖J_nom‖_F
    cond_home: np.ndarray  # cond₂ J at the home pose (the grid's pose nearest p = 0)
    cond_home_frobenius: np.ndarray  # ‖J‖_F ‖J⁻¹‖_F / 3 at the home pose
    cond_spread: np.ndarray  # max_p |cond₂ J(p) − cond₂ J_nom| / cond₂ J_nom
    rotation: np.ndarray  # max_p |φ(p)| [rad], the platform's parasitic rotation
    misfit: np.ndarray  # max_p, legs |n_i − R wp_i| [rad], the angle the R3 joints' clearance takes
    margin_loss: np.ndarray  # smallest reach/stroke margin over the grid, nominal minus as built [m] (> 0: lost)
    margin: np.ndarray  # that smallest margin as built [m] (< 0: a pose of the grid is out of reach or stroke)
    converged: np.ndarray  # bool: IK closed (:data:`LAST_STEP_TOL`) at every pose; the other fields are NaN if not


#: what :class:`Offnominal` reports, with units for printing
OFFNOMINAL_UNITS: dict[str, str] = {"constancy": "", "cond_home": "", "cond_home_frobenius": "", "cond_spread": "",
                                    "rotation": "rad", "misfit": "rad", "margin_loss": "m", "margin": "m", "converged": ""}
#: largest closure residual [m, rad] before the last Newton step of a converged IK (quadratic convergence leaves
#: ~1e-12 after it; a pose out of reach has no solution and Newton does not close)
LAST_STEP_TOL = 1e-6


def cond2(j, xp=np):
    """cond₂ of (..., 3, 3) matrices (σ_max/σ_min)."""
    s = xp.linalg.svd(j, compute_uv=False)
    return s[..., 0] / s[..., -1]


def cond_frobenius(j, xp=np):
    """‖J‖_F ‖J⁻¹‖_F / 3 of (..., 3, 3) matrices (1 where cond₂ = 1; smooth)."""
    return xp.sqrt(xp.sum(j**2, axis=(-2, -1)) * xp.sum(_inv3(j, xp) ** 2, axis=(-2, -1))) / 3.0


def home_index(poses) -> int:
    """Index of the pose nearest the home pose p = 0."""
    return int(np.argmin(np.linalg.norm(np.asarray(poses), axis=-1)))


def _metrics(design: PrrrDesign, errors, poses: np.ndarray, branch: int, xp=np) -> tuple:
    """The :class:`Offnominal` fields of ``errors`` (N, 3, N_ERRORS) at ``poses`` (P, 3), margin raw."""
    g = design.geometry
    par = kin.params_np(design)
    j_nom = np.asarray(kin.jacobian(par.beta, xp=np))
    cond_nom = float(cond2(j_nom))
    home = home_index(poses)
    dev = build(design, errors, xp)
    d, st = _start(design, dev, poses, branch, xp)
    st, ch, fac, resid = _ik_newton(d, st, NEWTON_STEPS, xp)
    j = _jacobian_from(fac, xp)
    dev_norm = xp.sqrt(xp.sum((j - j_nom) ** 2, axis=(-2, -1))) / float(np.linalg.norm(j_nom))
    cond = cond2(j, xp)
    bore = d.wp + _cross(st.phi[..., None, :], d.wp, xp)
    # margin: elbow reach from the solved θ2 with the as-built lengths (|ρ|² = d3² + d4² + 2 d3 d4 cos θ2),
    # stroke L/2 − |D − c_e| against the nominal stops
    d3 = xp.sqrt(_dot(d.l1, d.l1, xp))
    d4 = _dot(d.l2, kin.leg_frames(g.beta, xp=np).v, xp)
    rho = xp.sqrt(xp.maximum(d3**2 + d4**2 + 2.0 * d3 * d4 * xp.cos(st.theta[..., 1]), 0.0))
    reach = xp.minimum(rho - xp.abs(d3 - d4), d3 + d4 - rho)
    stroke = g.stroke / 2.0 - xp.abs(st.sliders - g.c_e)
    margin = xp.min(xp.min(xp.minimum(reach, stroke), axis=-1), axis=-1)
    converged = xp.all(resid <= LAST_STEP_TOL, axis=-1)  # NaN residuals fail too
    nan = xp.where(converged, 1.0, xp.nan)
    return (xp.max(dev_norm, axis=-1) * nan, cond[..., home] * nan, cond_frobenius(j[..., home, :, :], xp) * nan,
            xp.max(xp.abs(cond - cond_nom), axis=-1) / cond_nom * nan,
            xp.max(xp.sqrt(_dot(st.phi, st.phi, xp)), axis=-1) * nan,
            xp.max(xp.max(xp.sqrt(_dot(ch.n - bore, ch.n - bore, xp)), axis=-1), axis=-1) * nan, margin * nan,
            converged)


def offnominal(design: PrrrDesign, errors, poses=None, *, branch: int = BRANCH, chunk: int = 128) -> Offnominal:
    """What ``errors`` ``(N, 3, N_ERRORS)`` do to ``design`` over ``poses`` (:func:`pose_grid` by
    default): Jacobian constancy, cond(J), parasitic rotation, misfit, workspace margin loss. A device
    whose IK does not close at some pose (a pose out of its reach) has ``converged`` False and NaN
    elsewhere.
    Devices in chunks of ``chunk`` (the arrays of a chunk stay in cache). The kernels take ``xp``
    (numpy here; ``jax.numpy`` traces them for derivatives)."""
    errors = np.asarray(errors, dtype=float)
    poses = pose_grid() if poses is None else np.asarray(poses, dtype=float)
    n = errors.shape[0]
    parts = [_metrics(design, errors[c0:c0 + chunk], poses, branch) for c0 in range(0, n, chunk)]
    cols = [np.concatenate(c) for c in zip(*parts)]
    nominal = _metrics(design, np.zeros((1, 3, N_ERRORS)), poses, branch)
    return Offnominal(*cols[:-2], float(nominal[-2][0]) - cols[-2], *cols[-2:])
