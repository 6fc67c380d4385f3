"""Stability of seed 000's handle against a virtual wall: the paper's closed forms and the exact loop.

Closed forms (the paper's continuous model with the Padé hold 2/(2 + sT), eq 9–14)
---------------------------------------------------------------------------------
Characteristic cubic a0 s³ + a1 s² + a2 s + a3 (eq 15; eq 20 with the operator):

    a0 = T(I + R² m_h)
    a1 = 2(I + R² m_h) + T(B_m + R² b_h)
    a2 = 2(B_m + R² b_h + rR B_e) + R² k_h T
    a3 = 2rR K_e + 2R² k_h

from 1 + Z_h Y_s = 0 with Y_s of eq (12) and Z_h of eq (1). With m_h = b_h = 0 this is eq (20)
except that eq (20)/(14) print R k_h where R² k_h is needed (R k_h has units g·cm/s², the other
terms g·cm²/s²; the tip spring k_h enters the shaft equation through x = Rθ and M_h = R f_h,
hence R²). Hurwitz (eq 17, 21) for a cubic with positive coefficients: a1 a2 > a0 a3.

* eq (18)–(19): K_e < (2I + T B_m)(B_m + rR B_e) / (rR T I)   (no operator)
* eq (22):      k_h > [2rRT K_e I − 2(2I + T B_m)(B_m + rR B_e)] / (T² R² B_m)   (m_h = b_h = 0;
  the paper prints R, see above; its quoted 153 N/mm is not reproduced by either form: with R²
  the paper's case K_e = 10 N/mm, B_e = 30 g/s, T = 1 ms gives 231.6 N/mm)

Exact sampled loop
------------------
The paper's loop (eq 9, Fig 4) has only the zero-order hold — no extra computation delay: the
force computed from the sample x_k is held over [kT, (k+1)T). The wall's velocity is the
backward difference of the sampled position (section 1: "x_h … 可由位置传感器测得的运动信息后向
差分得到"). So with the exact ZOH discretisation (Φ, Γ) of the plant over T:

    z_{k+1} = Φ z_k + Γ f_k,   f_k = K_e x_k + B_e (x_k − x_{k−1}) / T,   z = [x, ẋ]

and the loop is stable iff the spectral radius ρ of its 3×3 (4×4 with ``delay_samples = 1``)
transition matrix is < 1. Verdicts use the margin (slowest modal decay rate ln ρ_i / T, relative
to the handle's b/m, evaluated in delta form on M − I so it stays exact as T → 0) with a fixed
band (``MARGIN_BAND``) far above rounding; the boundary K_e is the margin's root bracketed by a
geometric scan.

A one-sample computation delay (``delay_samples = 1``) is available for comparison only: it would
put the limit near a third of eq (19) (Colgate/Gil: ~2b/(3T) instead of 2b/T), against the
paper's measured 3.6–4.1 N/mm with a hand (Table 1).
"""

from __future__ import annotations

import dataclasses
import enum
import math
from dataclasses import dataclass

import numpy as np

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.design.handle.params import HandleDesign
from hapticopt.analysis.handle.model import N_PER_MM, Handle, Hold, discrete_plant, from_design, pade_closed_loop

#: |margin| below this is "marginal". The margin is the slowest modal decay rate relative to the
#: handle's mechanical rate b/m (``margin``); computed in delta form its rounding error is
#: ~1e-16·|eig(M − I)|/(T b/m) ≲ 1e-13 for T ≥ 1e-6 s, six decades below the band.
MARGIN_BAND = 1e-7


class Verdict(enum.Enum):
    STABLE = "stable"
    MARGINAL = "marginal"
    UNSTABLE = "unstable"


class LimitStatus(enum.Enum):
    OK = "ok"  #: a stable K_e < limit ≤ unstable K_e was bracketed and the root found
    UNSTABLE_WITHOUT_WALL = "unstable_without_wall"  #: no K_e > 0 is stable (limit NaN)
    NOT_FOUND = "not_found"  #: stable up to the scan's end (limit NaN)


def verdict(margin: float) -> Verdict:
    """Classify a stability margin (see ``margin``) with the fixed ``MARGIN_BAND``."""
    if margin > MARGIN_BAND:
        return Verdict.STABLE
    if margin < -MARGIN_BAND:
        return Verdict.UNSTABLE
    return Verdict.MARGINAL


# ------------------------------------------------------------------------------ closed forms
def cubic(handle: Handle) -> np.ndarray:
    """(a0, a1, a2, a3) of eq (15)/(20) in SI [kg·m²·s, kg·m², kg·m²/s, kg·m²/s²] (R² k_h)."""
    T, I, Bm = handle.period_s, handle.inertia_kg_m2, handle.motor_damping_N_m_s
    R2, rR = handle.lever_m**2, handle.rR_m2
    op = handle.operator
    Ieq = I + R2 * op.mass
    Beq = Bm + R2 * op.damping
    return np.array([
        T * Ieq,
        2.0 * Ieq + T * Beq,
        2.0 * (Beq + rR * handle.wall_damping_N_s_per_m) + R2 * op.stiffness * T,
        2.0 * rR * handle.wall_stiffness_N_per_m + 2.0 * R2 * op.stiffness,
    ])


def eq18_stiffness_limit(handle: Handle) -> float:
    """K_e at which a1 a2 = a0 a3 (eq 18; with the operator the same root of eq 21) [N/m]."""
    a0, a1, a2, _ = cubic(handle)
    R2k = handle.lever_m**2 * handle.operator.stiffness
    return (a1 * a2 / a0 - 2.0 * R2k) / (2.0 * handle.rR_m2)


def eq22_critical_operator_stiffness(handle: Handle) -> float:
    """Eq (22) with R²: the k_h above which the Padé loop is stable (m_h = b_h = 0) [N/m]."""
    T, I, Bm = handle.period_s, handle.inertia_kg_m2, handle.motor_damping_N_m_s
    rR, R2 = handle.rR_m2, handle.lever_m**2
    Ke, Be = handle.wall_stiffness_N_per_m, handle.wall_damping_N_s_per_m
    return (2.0 * rR * T * Ke * I - 2.0 * (2.0 * I + T * Bm) * (Bm + rR * Be)) / (T**2 * R2 * Bm)


# ------------------------------------------------------------------------------ exact sampled loop
def loop_delta(handle: Handle, *, delay_samples: int = 0, _plant=None) -> np.ndarray:
    """M − I for the exact sampled loop's transition matrix M, state [x, ẋ, x_{k−1}] (+ f_{k−1}
    with one sample of delay), built from Φ − I directly (no cancellation as T → 0)."""
    if delay_samples not in (0, 1):
        raise ValueError(f"delay_samples = {delay_samples!r}: allowed 0 or 1 [samples]")
    PhiI, Gam = discrete_plant(handle) if _plant is None else _plant
    g = Gam[:, 0]
    T = handle.period_s
    kx = handle.wall_stiffness_N_per_m + handle.wall_damping_N_s_per_m / T
    kp = -handle.wall_damping_N_s_per_m / T
    if delay_samples == 0:
        E = np.zeros((3, 3))
        E[:2, :2] = PhiI
        E[:2, 0] += g * kx
        E[:2, 2] = g * kp
        E[2, 0], E[2, 2] = 1.0, -1.0
        return E
    E = np.zeros((4, 4))
    E[:2, :2] = PhiI
    E[:2, 3] = g
    E[2, 0], E[2, 2] = 1.0, -1.0
    E[3, 0], E[3, 2], E[3, 3] = kx, kp, -1.0
    return E


def _delta_margin(E: np.ndarray, T: float, rate: float) -> np.ndarray:
    """−max ln|1 + e|/T over the eigenvalues e of E = M − I, divided by ``rate`` (batched)."""
    e = np.linalg.eigvals(E)
    with np.errstate(divide="ignore"):  # an eigenvalue of M at exactly 0 (deadbeat) → σ = −inf
        sigma = np.log1p(2.0 * e.real + (e.real**2 + e.imag**2)) / (2.0 * T)
    return -np.max(sigma, axis=-1) / rate


def margin(handle: Handle, *, hold: Hold = Hold.EXACT, delay_samples: int = 0, _plant=None) -> float:
    """Stability margin [-]: −(largest modal growth rate [1/s]) / (b/m), the handle's own
    mechanical decay rate; > 0 stable. Exact hold: growth rate ln ρ_i / T per mode, evaluated as
    log1p on M − I (exact as T → 0); Padé: max Re λ of the continuous loop."""
    rate = handle.damping_N_s_per_m / handle.mass_kg
    if hold is Hold.PADE:
        lam = np.linalg.eigvals(pade_closed_loop(handle).A)
        return float(-np.max(lam.real) / rate)
    E = loop_delta(handle, delay_samples=delay_samples, _plant=_plant)
    return float(_delta_margin(E, handle.period_s, rate))


@dataclass(frozen=True)
class StiffnessLimit:
    """Largest stable K_e [N/m] (NaN unless status is OK), with the bracket that proves it."""

    value_N_per_m: float
    status: LimitStatus
    stable_below_N_per_m: float
    unstable_at_N_per_m: float

    @property
    def value_N_per_mm(self) -> float:
        return self.value_N_per_m / N_PER_MM


def stiffness_limit(handle: Handle, *, hold: Hold = Hold.EXACT, delay_samples: int = 0,
                    rtol: float = 1e-10) -> StiffnessLimit:
    """Root of the margin in K_e (the handle's own K_e is ignored) [N/m].

    Scan: K = 1e-3·K_ref (must be stable), then K_ref·2^j for j = −2, −1, 0, … up to 1e4·K_ref
    (K_ref = 2b/(T r/R), Colgate's bound at the shaft); the first unstable point and the last
    stable one bracket the root of the margin, found by Brent's method.
    """
    from scipy.optimize import brentq  # lazy: a heavy import (tests/test_layers.py LAZY)
    rate = handle.damping_N_s_per_m / handle.mass_kg
    if hold is Hold.PADE:
        h0 = dataclasses.replace(handle, wall_stiffness_N_per_m=0.0)
        A0 = pade_closed_loop(h0).A
        dA = np.zeros_like(A0)
        dA[2, 0] = 2.0 / handle.period_s

        def g(K: float) -> float:
            return float(-np.max(np.linalg.eigvals(A0 + K * dA).real) / rate)
    else:
        plant_ = discrete_plant(handle)
        E0 = loop_delta(dataclasses.replace(handle, wall_stiffness_N_per_m=0.0), delay_samples=delay_samples,
                        _plant=plant_)
        dE = np.zeros_like(E0)
        if delay_samples == 0:
            dE[:2, 0] = plant_[1][:, 0]
        else:
            dE[3, 0] = 1.0

        def g(K: float) -> float:
            return float(_delta_margin(E0 + K * dE, handle.period_s, rate))

    ref = 2.0 * handle.damping_N_s_per_m / (handle.period_s * handle.transmission)
    lo = 1e-3 * ref
    if verdict(g(lo)) is not Verdict.STABLE:
        return StiffnessLimit(math.nan, LimitStatus.UNSTABLE_WITHOUT_WALL, math.nan, lo)
    hi = 0.25 * ref
    while g(hi) >= 0.0:
        lo, hi = hi, 2.0 * hi
        if hi > 1e4 * ref:
            return StiffnessLimit(math.nan, LimitStatus.NOT_FOUND, lo, math.nan)
    K = brentq(g, lo, hi, rtol=rtol, xtol=1e-12 * ref)
    return StiffnessLimit(K, LimitStatus.OK, lo, hi)


def max_stable_stiffness_N_per_mm(handle: Handle, *, period_s: float | None = None,
                                  wall_damping_N_s_per_m: float | None = None,
                                  operator_stiffness_N_per_m: float | None = None,
                                  hold: Hold = Hold.EXACT) -> float:
    """Largest stable K_e [N/mm] against T [s], B_e [N·s/m] and k_h [N/m]; NaN if none is found."""
    h = handle
    if period_s is not None:
        h = dataclasses.replace(h, period_s=period_s)
    if wall_damping_N_s_per_m is not None:
        h = dataclasses.replace(h, wall_damping_N_s_per_m=wall_damping_N_s_per_m)
    if operator_stiffness_N_per_m is not None:
        h = dataclasses.replace(h, operator=dataclasses.replace(h.operator, stiffness=operator_stiffness_N_per_m))
    return stiffness_limit(h, hold=hold).value_N_per_mm


def critical_operator_stiffness(handle: Handle, *, hold: Hold = Hold.EXACT) -> float:
    """Smallest k_h [N/m] that makes the handle's own K_e, B_e stable (the exact counterpart of
    eq 22 for ``Hold.EXACT``): bisection on the margin over k_h ∈ [0, 1e9] N/m, 60 halvings.
    0 if stable without a hand, NaN if even 1e9 N/m does not stabilise."""

    def g(kh: float) -> float:
        op = dataclasses.replace(handle.operator, stiffness=kh)
        return margin(dataclasses.replace(handle, operator=op), hold=hold)

    if g(0.0) > MARGIN_BAND:
        return 0.0
    lo, hi = 0.0, 1e9
    if not g(hi) > MARGIN_BAND:
        return math.nan
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if g(mid) > 0.0 else (mid, hi)
    return hi


@dataclass(frozen=True)
class PadeComparison:
    """K_e limits per period: the paper's Padé hold vs the exact ZOH (same handle otherwise)."""

    period_s: np.ndarray
    pade_N_per_mm: np.ndarray
    exact_N_per_mm: np.ndarray

    @property
    def relative_difference(self) -> np.ndarray:
        """(Padé − exact)/exact [-]."""
        return self.pade_N_per_mm / self.exact_N_per_mm - 1.0


def pade_vs_exact(handle: Handle, periods_s) -> PadeComparison:
    T = np.asarray(periods_s, dtype=float)
    if T.ndim != 1 or np.any(~np.isfinite(T)) or np.any(T <= 0.0):
        raise ValueError(f"periods_s = {periods_s!r}: a 1-D array of finite values > 0 [s]")
    p = [max_stable_stiffness_N_per_mm(handle, period_s=t, hold=Hold.PADE) for t in T]
    e = [max_stable_stiffness_N_per_mm(handle, period_s=t, hold=Hold.EXACT) for t in T]
    return PadeComparison(T, np.array(p), np.array(e))


@dataclass(frozen=True)
class ZWidthMap:
    """Margins on a B_e × K_e grid and the K_e boundary per B_e (exact loop)."""

    wall_damping_N_s_per_m: np.ndarray  # (nB,)
    wall_stiffness_N_per_m: np.ndarray  # (nK,)
    margin: np.ndarray  # (nB, nK): ``margin`` of each cell [-]
    boundary_N_per_m: np.ndarray  # (nB,), NaN where no limit was found
    boundary_status: tuple[LimitStatus, ...]

    @property
    def stable(self) -> np.ndarray:
        return self.margin > MARGIN_BAND


def zwidth_map(handle: Handle, wall_damping_N_s_per_m, wall_stiffness_N_per_m, *,
               delay_samples: int = 0) -> ZWidthMap:
    B = np.asarray(wall_damping_N_s_per_m, dtype=float)
    K = np.asarray(wall_stiffness_N_per_m, dtype=float)
    plant_ = discrete_plant(handle)
    M = np.empty((B.size, K.size))
    bnd, st = [], []
    for i, be in enumerate(B):
        hb = dataclasses.replace(handle, wall_damping_N_s_per_m=float(be))
        mats = np.stack([loop_delta(dataclasses.replace(hb, wall_stiffness_N_per_m=float(k)),
                                    delay_samples=delay_samples, _plant=plant_) for k in K])
        M[i] = _delta_margin(mats, handle.period_s, handle.damping_N_s_per_m / handle.mass_kg)
        lim = stiffness_limit(hb, delay_samples=delay_samples, rtol=1e-8)
        bnd.append(lim.value_N_per_m)
        st.append(lim.status)
    return ZWidthMap(B, K, M, np.array(bnd), tuple(st))


# ------------------------------------------------------------------------------ evaluator
@dataclass(frozen=True)
class HandleStability:
    """Stability summary of a handle with its wall and operator. Non-ok status → NaN limits."""

    status: LimitStatus  #: of the exact boundary
    verdict: Verdict  #: of the handle's own K_e, B_e in the exact loop
    margin: float  #: exact-loop margin of the handle's own K_e, B_e [-]
    exact_limit_N_per_mm: float  #: max stable K_e, exact ZOH, no computation delay
    pade_limit_N_per_mm: float  #: max stable K_e of the paper's Padé loop (eq 18/21)
    eq22_operator_stiffness_N_per_mm: float  #: eq (22) with R² for the handle's K_e, B_e
    exact_operator_stiffness_N_per_mm: float  #: its exact-hold counterpart (NaN if none ≤ 1e9 N/m)


def analyse(handle: Handle) -> HandleStability:
    """Pure evaluator: the closed forms and the exact loop for ``handle`` (SI in, N/mm out)."""
    ex = stiffness_limit(handle)
    pa = stiffness_limit(handle, hold=Hold.PADE)
    m = margin(handle)
    ok = ex.status is LimitStatus.OK
    return HandleStability(
        status=ex.status,
        verdict=verdict(m),
        margin=m,
        exact_limit_N_per_mm=ex.value_N_per_mm if ok else math.nan,
        pade_limit_N_per_mm=pa.value_N_per_mm if ok else math.nan,
        eq22_operator_stiffness_N_per_mm=eq22_critical_operator_stiffness(handle) / N_PER_MM,
        exact_operator_stiffness_N_per_mm=critical_operator_stiffness(handle) / N_PER_MM,
    )


#: grids of the limit's dependence reported by the evaluator (T [s], B_e [N·s/m], k_h [N/m]):
#: the paper's conclusions (limit falls with T, rises with B_e, a stiffer operator stabilises)
SWEEP_PERIODS_S = (0.5e-3, 1e-3, 2e-3, 5e-3)
SWEEP_WALL_DAMPING_N_S_PER_M = (0.0, 0.03, 1.0, 10.0, 100.0)
SWEEP_OPERATOR_STIFFNESS_N_PER_M = (0.0, 1e3, 1e4, 1e5)


@dataclass(frozen=True, kw_only=True)
class StabilityResult:
    """The handle evaluator's result (``hapticopt evaluate``): limits in N/mm, NaN unless ok."""

    summary: HandleStability
    eq19_limit_N_per_mm: float  #: eq (18)–(19), Padé closed form, the design's B_e, no operator
    vs_period_N_per_mm: tuple[float, ...]  #: exact limit at SWEEP_PERIODS_S
    vs_wall_damping_N_per_mm: tuple[float, ...]  #: exact limit at SWEEP_WALL_DAMPING_N_S_PER_M
    vs_operator_stiffness_N_per_mm: tuple[float, ...]  #: exact limit at SWEEP_OPERATOR_STIFFNESS_N_PER_M
    status: Status
    message: str = ""

    def metrics(self) -> dict[str, object]:
        s = self.summary
        return {
            "max_stable_stiffness_N_per_mm": s.exact_limit_N_per_mm,
            "pade_stable_stiffness_N_per_mm": s.pade_limit_N_per_mm,
            "pade_minus_exact_pct": 100.0 * (s.pade_limit_N_per_mm / s.exact_limit_N_per_mm - 1.0),
            "eq19_stable_stiffness_N_per_mm": self.eq19_limit_N_per_mm,
            "wall_stable": s.verdict is Verdict.STABLE,
            "wall_margin": s.margin,
            "eq22_operator_stiffness_N_per_mm": s.eq22_operator_stiffness_N_per_mm,
            "critical_operator_stiffness_N_per_mm": s.exact_operator_stiffness_N_per_mm,
            "max_stable_stiffness_vs_period_N_per_mm": list(self.vs_period_N_per_mm),
            "sweep_period_ms": [t * 1e3 for t in SWEEP_PERIODS_S],
            "max_stable_stiffness_vs_wall_damping_N_per_mm": list(self.vs_wall_damping_N_per_mm),
            "sweep_wall_damping_Ns_per_m": list(SWEEP_WALL_DAMPING_N_S_PER_M),
            "max_stable_stiffness_vs_operator_stiffness_N_per_mm": list(self.vs_operator_stiffness_N_per_mm),
            "sweep_operator_stiffness_N_per_mm": [k / N_PER_MM for k in SWEEP_OPERATOR_STIFFNESS_N_PER_M],
        }


def evaluate(design: HandleDesign, *, fidelity: Fidelity = Fidelity.STANDARD) -> StabilityResult:
    """Registry evaluator: eq 15–22 and the exact sampled loop for the described handle, wall and hand.

    Status ``ok`` when the exact boundary was found and the design's own wall K_e lies below it;
    ``not-met`` (numbers kept) when the boundary was found but the design's wall is not below it
    by the margin band (the rendered wall is unstable or marginal: ``wall_stable`` false,
    ``wall_margin`` says by how much);
    ``unstable`` when no wall stiffness is stable (the handle with this B_e and hand is unstable
    alone: limits NaN); ``failed`` when the scan found no boundary.
    """
    del fidelity  # closed forms and eigenvalues: no accuracy knob
    h = from_design(design)
    s = analyse(h)
    no_hand = dataclasses.replace(h, operator=dataclasses.replace(h.operator, mass=0.0, damping=0.0, stiffness=0.0))
    eq19 = eq18_stiffness_limit(no_hand) / N_PER_MM
    sweep = lambda **kw: max_stable_stiffness_N_per_mm(h, **kw)  # noqa: E731
    vs_T = tuple(sweep(period_s=t) for t in SWEEP_PERIODS_S)
    vs_B = tuple(sweep(wall_damping_N_s_per_m=b) for b in SWEEP_WALL_DAMPING_N_S_PER_M)
    vs_k = tuple(sweep(operator_stiffness_N_per_m=k) for k in SWEEP_OPERATOR_STIFFNESS_N_PER_M)
    if s.status is LimitStatus.OK:
        return StabilityResult(summary=s, eq19_limit_N_per_mm=eq19, vs_period_N_per_mm=vs_T,
                               vs_wall_damping_N_per_mm=vs_B, vs_operator_stiffness_N_per_mm=vs_k,
                               status=Status.OK if s.verdict is Verdict.STABLE else Status.NOT_MET,
                               message="" if s.verdict is Verdict.STABLE else
                               f"the rendered wall is {s.verdict.value}: the design's K_e = "
                               f"{h.wall_stiffness_N_per_m / N_PER_MM:g} N/mm against the limit "
                               f"{s.exact_limit_N_per_mm:.4g} N/mm (margin {s.margin:.3g}, stable above {MARGIN_BAND:g})")
    why = ("no wall stiffness is stable: the handle with this B_e and hand is unstable on its own"
           if s.status is LimitStatus.UNSTABLE_WITHOUT_WALL else "stable up to the scan's end (1e4 × 2b/(T r/R))")
    return StabilityResult(summary=s, eq19_limit_N_per_mm=math.nan, vs_period_N_per_mm=vs_T,
                           vs_wall_damping_N_per_mm=vs_B, vs_operator_stiffness_N_per_mm=vs_k,
                           status=Status.UNSTABLE if s.status is LimitStatus.UNSTABLE_WITHOUT_WALL else Status.FAILED,
                           message=why)
