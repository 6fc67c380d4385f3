"""Iterative optimal impedance control (IOIC) of seed 001, section 2 (eq 3–10, 27–33).

One Cartesian axis. State X = [e_p, ė_p, f] (eq 3), e_p = x_r − x_d [m], f [N] the operator's
force of eq 2, input u = ë_p [m/s²] (eq 5), u = −K X with K = [K_d/M_d, B_d/M_d, 1/M_d].

* :func:`riccati_optimum` — the model optimum (OIC): the LQR of eq 6 solved with
  ``scipy.linalg.solve_continuous_are`` → P*, K* (eq 30) and the impedance M*, B*, K* (eq 33).
* :func:`collect_data` — the data phase (eq 7, 8): the plant runs under u = −K_0 X + v_n for
  the first ``duration`` seconds, and the Kronecker data of eq 7 are integrated over
  ``n_intervals`` sampling intervals (RK4, the integrals are extra states of the same RK4).
* :func:`policy_iteration` — off-policy policy iteration (eq 9; Jiang & Jiang 2012,
  Automatica 48(10) 2699, Algorithm 1): least squares for P_k and K_{k+1} from the data only,
  until ‖P_k − P_{k−1}‖_F ≤ ε. Refuses (status ``not_exciting``, NaN gains) when the data
  matrix [I_xx, I_xu] has fewer rows than unknowns, is rank-deficient, or its reciprocal
  condition number (columns scaled to unit norm) is below :data:`RCOND_MIN`.
* :func:`soft_switch` — eq 10, the cosine blend from K_0 to the learned gain over T_s.
* :func:`simulate_outer_loop` — the section 4.1 example: FIC (K_0 throughout), OIC (K*), IOIC
  (K_0 + v_n for 0.5 s, learn, soft switch), square-wave x_d of amplitude 0.4 m and period 10 s.

Errata applied (the paper as printed → here):
* eq 9 prints θ_k = δ_XX vec(Q_k); Jiang & Jiang's right-hand side is −I_xx vec(Q_k) (the
  Lyapunov identity XᵀP X|_{t_i}^{t_{i+1}} = −∫Xᵀ(Q + K_kᵀRK_k)X dt + 2∫(u + K_k X)ᵀ R K_{k+1} X dt).
* eq 28 prints v_n = Σ_j (0.05/j) sin(100 t): all ten terms share one frequency, i.e. a single
  sinusoid of amplitude 0.05·H_10 = 0.1464 m/s². It is used as printed; over the 0.5 s data
  phase the closed-loop transient it excites (plus the initial error of the square wave)
  makes all 9 unknowns identifiable (measured rcond ≈ 3e-4). :meth:`ExplorationNoise.multisine`
  is a genuinely varied, seeded alternative (ten random frequencies and phases).
"""

from __future__ import annotations

import dataclasses
import enum
import math

import numpy as np
import scipy.linalg

from hapticopt.analysis.loop.operator import Operator, state_space

#: Data matrices whose column-scaled reciprocal condition number is below this are refused
#: (``not_exciting``): the data cannot determine the nine unknowns at all. From the exploration sweep
#: of docs/seed001.md (scripts/accuracy/accuracy_seed001_devices.py --exploration): without
#: exploration the devices' data sit at 1.2e-9 (master) and 3.9e-9 (3-PRRR) — encoder quantization
#: and tracking errors lift the smallest singular value without informing it (a gain learned from
#: them had K3 = −9.8) — and the exact simulation's at 3.4e-17; the weakest exploration swept
#: (eq 28 × 0.001) gives 1.5e-5 and 2.8e-5, the shortest exciting data of the simulation 2.4e-6.
#: The band sits between, ≥ 1.4 decades from each. Whether exciting data were informative *enough*
#: is not this band's verdict: the learned M, B, K against the tolerance of the optimum is
#: (:func:`hapticopt.analysis.control.ioic_online.impedance_verdict`; the × 0.001 … × 0.1 runs pass
#: this band and miss the tolerance by 13 % to 100×).
RCOND_MIN = 1e-7

#: Frequency band [rad/s] of the seeded multi-sine exploration: up to eq 28's 100 rad/s, down to
#: 2π / 0.5 s (one period within §4.1's data phase).
MULTISINE_BAND = (2 * math.pi / 0.5, 100.0)

#: Allowed integrator steps of the outer-loop simulation [s].
STEP_RANGE = (1e-5, 0.02)


class LearningStatus(enum.Enum):
    OK = "ok"
    NOT_EXCITING = "not_exciting"
    NOT_CONVERGED = "not_converged"


class Strategy(enum.Enum):
    FIC = "fic"  # fixed impedance K_0
    OIC = "oic"  # model-optimal K* (knows A)
    IOIC = "ioic"  # learned from data, soft switch


# --------------------------------------------------------------------------------------------
# Model optimum (eq 6, 30, 33)


@dataclasses.dataclass(frozen=True, kw_only=True)
class OptimalImpedance:
    """LQR optimum of eq 6. p: (n, n) [Riccati solution], k: (m, n) gain [1/s², 1/s, 1/kg];
    mass [kg], damping [N·s/m], stiffness [N/m] of the impedance model eq 1 (M* = 1/K3,
    B* = K2/K3, K* = K1/K3)."""

    p: np.ndarray
    k: np.ndarray
    mass: float
    damping: float
    stiffness: float


def impedance_from_gain(k: np.ndarray) -> tuple[float, float, float]:
    """(M_d [kg], B_d [N·s/m], K_d [N/m]) from K = [K_d/M_d, B_d/M_d, 1/M_d] (eq 5)."""
    k = np.asarray(k, dtype=float).reshape(-1)
    return 1.0 / k[2], k[1] / k[2], k[0] / k[2]


def riccati_optimum(a: np.ndarray, b: np.ndarray, q: np.ndarray, r: np.ndarray) -> OptimalImpedance:
    """Solve AᵀP + PA − PBR⁻¹BᵀP + Q = 0 and K* = R⁻¹BᵀP* (eq 6 → eq 30)."""
    a, b, q, r = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (a, b, q, r))
    p = scipy.linalg.solve_continuous_are(a, b, q, r)
    k = np.linalg.solve(r, b.T @ p)
    mass, damping, stiffness = impedance_from_gain(k)
    return OptimalImpedance(p=p, k=k, mass=mass, damping=damping, stiffness=stiffness)


# --------------------------------------------------------------------------------------------
# Exploration noise (eq 8, 28)


@dataclasses.dataclass(frozen=True, kw_only=True)
class ExplorationNoise:
    """v_n(t) = Σ_j a_j sin(ω_j t + φ_j) [m/s²]; a_j [m/s²], ω_j [rad/s], φ_j [rad]."""

    amplitudes: tuple[float, ...]
    frequencies: tuple[float, ...]
    phases: tuple[float, ...]

    def __post_init__(self) -> None:
        if not (len(self.amplitudes) == len(self.frequencies) == len(self.phases)):
            raise ValueError("ExplorationNoise: amplitudes, frequencies and phases must have the "
                             f"same length, got {len(self.amplitudes)}, {len(self.frequencies)}, "
                             f"{len(self.phases)}")

    @classmethod
    def printed(cls) -> ExplorationNoise:
        """Eq 28 as printed: a_j = 0.05/j, ω_j = 100 rad/s, φ_j = 0, j = 1..10."""
        return cls(amplitudes=tuple(0.05 / j for j in range(1, 11)),
                   frequencies=(100.0,) * 10, phases=(0.0,) * 10)

    @classmethod
    def multisine(cls, seed: int, *, band: tuple[float, float] = MULTISINE_BAND) -> ExplorationNoise:
        """A seeded random multi-sine: eq 28's ten amplitudes a_j = 0.05/j [m/s²], ten frequencies
        drawn log-uniformly from ``band`` [rad/s] and ten phases from U[0, 2π), all from ``seed``
        (numpy's default generator). Unlike eq 28 as printed (one 100 rad/s sinusoid) the ten terms
        differ in frequency, so the data phase sees a genuinely varied input."""
        lo, hi = band
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
            raise ValueError(f"ExplorationNoise.multisine: band = {band!r} rad/s must satisfy 0 < low < high")
        rng = np.random.default_rng(seed)
        freqs = np.exp(rng.uniform(math.log(lo), math.log(hi), 10))
        phases = rng.uniform(0.0, 2 * np.pi, 10)
        return cls(amplitudes=tuple(0.05 / j for j in range(1, 11)),
                   frequencies=tuple(float(v) for v in freqs), phases=tuple(float(v) for v in phases))

    @classmethod
    def zero(cls) -> ExplorationNoise:
        return cls(amplitudes=(), frequencies=(), phases=())

    def __call__(self, t: float | np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        a = np.asarray(self.amplitudes, dtype=float)
        w = np.asarray(self.frequencies, dtype=float)
        ph = np.asarray(self.phases, dtype=float)
        return np.sum(a * np.sin(w * t[..., None] + ph), axis=-1)

# --------------------------------------------------------------------------------------------
# Data phase (eq 7, 8)


@dataclasses.dataclass(frozen=True, kw_only=True)
class LearningData:
    """Kronecker data of eq 7 over N sampling intervals.

    t: (N+1,) interval boundaries [s]; x: (N+1, n) state there; ixx: (N, n, n) ∫ X Xᵀ dt;
    iux: (N, m, n) ∫ u Xᵀ dt over each interval; t_fine, x_fine, u_fine: the integrator grid.
    """

    t: np.ndarray
    x: np.ndarray
    ixx: np.ndarray
    iux: np.ndarray
    t_fine: np.ndarray
    x_fine: np.ndarray
    u_fine: np.ndarray


def _check_step(name: str, value: float, allowed: tuple[float, float]) -> None:
    if not (math.isfinite(value) and allowed[0] <= value <= allowed[1]):
        raise ValueError(f"{name} = {value!r} s is outside the allowed range "
                         f"[{allowed[0]:g}, {allowed[1]:g}] s")


def collect_data(a: np.ndarray, b: np.ndarray, k0: np.ndarray, noise: ExplorationNoise,
                 x0: np.ndarray, *, duration: float = 0.5, n_intervals: int = 50,
                 substeps: int = 10) -> LearningData:
    """Run the plant Ẋ = AX + Bu, u = −K_0 X + v_n(t) (eq 4, 8) over [0, duration] and integrate
    the data of eq 7 on ``n_intervals`` equal intervals, each with ``substeps`` RK4 steps.

    A and B stand for the physical plant (the human + impedance dynamics); the learner only
    receives the returned data. Default: 0.5 s, 50 intervals (seed 001 §4.1), 1 ms RK4 steps
    (63 steps per period of the 100 rad/s noise).
    """
    if not (isinstance(n_intervals, int) and n_intervals >= 1):
        raise ValueError(f"n_intervals = {n_intervals!r}: must be an integer ≥ 1")
    if not (isinstance(substeps, int) and substeps >= 1):
        raise ValueError(f"substeps = {substeps!r}: must be an integer ≥ 1")
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"duration = {duration!r} s: must be finite and > 0")
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    k0 = np.atleast_2d(np.asarray(k0, dtype=float))
    n, m = b.shape
    h = duration / (n_intervals * substeps)
    _check_step("data step (duration / (n_intervals·substeps))", h, STEP_RANGE)

    def rhs(t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        u = -k0 @ x + noise(t)
        return a @ x + b @ u, u

    def aug(t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        dx, u = rhs(t, x)
        return dx, np.outer(x, x), np.outer(u, x)

    x = np.asarray(x0, dtype=float).copy()
    n_steps = n_intervals * substeps
    t_fine = h * np.arange(n_steps + 1)
    x_fine = np.empty((n_steps + 1, n))
    u_fine = np.empty((n_steps + 1, m))
    ixx = np.zeros((n_intervals, n, n))
    iux = np.zeros((n_intervals, m, n))
    x_fine[0] = x
    u_fine[0] = rhs(0.0, x)[1]
    for i in range(n_intervals):
        for s in range(substeps):
            j = i * substeps + s
            t = t_fine[j]
            k1 = aug(t, x)
            k2 = aug(t + h / 2, x + h / 2 * k1[0])
            k3 = aug(t + h / 2, x + h / 2 * k2[0])
            k4 = aug(t + h, x + h * k3[0])
            x = x + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            ixx[i] += h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            iux[i] += h / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2])
            x_fine[j + 1] = x
            u_fine[j + 1] = rhs(t_fine[j + 1], x)[1]
    idx = substeps * np.arange(n_intervals + 1)
    return LearningData(t=t_fine[idx], x=x_fine[idx], ixx=ixx, iux=iux,
                        t_fine=t_fine, x_fine=x_fine, u_fine=u_fine)


# --------------------------------------------------------------------------------------------
# Policy iteration (eq 9)


@dataclasses.dataclass(frozen=True, kw_only=True)
class LearningResult:
    """Outcome of :func:`policy_iteration`.

    status: ``ok`` only when the data are exciting and ‖P_k − P_{k−1}‖_F ≤ eps was reached;
    k (m, n) and p (n, n) are NaN otherwise. iterations: least-squares solves done.
    rank / rcond: of the data matrix [I_xx, I_xu] (N × (n(n+1)/2 + mn)); rcond after scaling
    columns to unit norm. k_history, p_history: K_1.., P_0.. per iteration (K_0 first).
    """

    status: LearningStatus
    k: np.ndarray
    p: np.ndarray
    iterations: int
    rank: int
    rcond: float
    n_rows: int
    n_unknowns: int
    k_history: np.ndarray
    p_history: np.ndarray
    message: str


def _sym_index(n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.triu_indices(n)


def data_matrix(data: LearningData) -> np.ndarray:
    """[I_xx, I_xu] of Jiang & Jiang 2012 (rank condition under eq 8): the unique products
    x_i x_j (i ≤ j) integrated per interval, then ∫ X ⊗ u; shape (N, n(n+1)/2 + nm)."""
    iu, ju = _sym_index(data.ixx.shape[1])
    n_rows = data.ixx.shape[0]
    return np.concatenate([data.ixx[:, iu, ju], data.iux.reshape(n_rows, -1)], axis=1)


def _scaled_rcond(mat: np.ndarray) -> tuple[int, float]:
    norms = np.linalg.norm(mat, axis=0)
    if mat.shape[0] < mat.shape[1] or np.any(norms == 0.0):
        s = np.linalg.svd(mat, compute_uv=False) if mat.size else np.zeros(1)
        return int(np.sum(s > s.max(initial=0.0) * max(mat.shape) * np.finfo(float).eps)), 0.0
    s = np.linalg.svd(mat / norms, compute_uv=False)
    rank = int(np.sum(s > s[0] * max(mat.shape) * np.finfo(float).eps))
    return rank, float(s[-1] / s[0])


def policy_iteration(data: LearningData, k0: np.ndarray, q: np.ndarray, r: np.ndarray, *,
                     eps: float = 1e-8, max_iterations: int = 30) -> LearningResult:
    """Off-policy policy iteration on recorded data (eq 9, Jiang & Jiang 2012 Algorithm 1).

    For each interval [t_i, t_{i+1}] and iteration k, the unknowns P_k (symmetric) and K_{k+1}
    satisfy
        X(t_{i+1})ᵀP_kX(t_{i+1}) − X(t_i)ᵀP_kX(t_i) − 2∫(u + K_kX)ᵀ R K_{k+1} X dt
            = −∫ Xᵀ(Q + K_kᵀRK_k) X dt,
    solved by least squares over all intervals (eq 9). Stops when ‖P_k − P_{k−1}‖_F ≤ eps.
    """
    k0 = np.atleast_2d(np.asarray(k0, dtype=float))
    q = np.atleast_2d(np.asarray(q, dtype=float))
    r = np.atleast_2d(np.asarray(r, dtype=float))
    n_rows, n = data.ixx.shape[:2]
    m = data.iux.shape[1]
    n_unknowns = n * (n + 1) // 2 + m * n
    rank, rcond = _scaled_rcond(data_matrix(data))
    nan_k = np.full((m, n), np.nan)
    nan_p = np.full((n, n), np.nan)

    def refuse(status: LearningStatus, msg: str, it: int = 0, kh=None, ph=None) -> LearningResult:
        return LearningResult(status=status, k=nan_k, p=nan_p, iterations=it, rank=rank,
                              rcond=rcond, n_rows=n_rows, n_unknowns=n_unknowns,
                              k_history=np.array([k0]) if kh is None else np.array(kh),
                              p_history=np.empty((0, n, n)) if ph is None else np.array(ph),
                              message=msg)

    if n_rows < n_unknowns:
        return refuse(LearningStatus.NOT_EXCITING,
                      f"{n_rows} sampling intervals < {n_unknowns} unknowns: too few rows")
    if rank < n_unknowns or rcond < RCOND_MIN:
        return refuse(LearningStatus.NOT_EXCITING,
                      f"data matrix rank {rank} of {n_unknowns}, rcond {rcond:.1e} "
                      f"(required ≥ {RCOND_MIN:.0e}): exploration does not excite the data")

    iu, ju = _sym_index(n)
    weight = np.where(iu == ju, 1.0, 2.0)  # x_i x_j (i<j) appears twice in XᵀPX
    x_next = np.einsum("ni,nj->nij", data.x[1:], data.x[1:])
    x_prev = np.einsum("ni,nj->nij", data.x[:-1], data.x[:-1])
    dxx = (x_next - x_prev)[:, iu, ju] * weight
    k = k0
    p_prev = None
    k_hist, p_hist = [k0], []
    for it in range(1, max_iterations + 1):
        qk = q + k.T @ r @ k
        w = data.iux + np.einsum("mj,nji->nmi", k, data.ixx)  # ∫ (u + K_k X) Xᵀ dt
        theta = np.concatenate([dxx, -2.0 * np.einsum("ab,nbi->nai", r, w).reshape(n_rows, -1)],
                               axis=1)
        xi = -np.einsum("nij,ij->n", data.ixx, qk)
        sol = np.linalg.lstsq(theta, xi, rcond=None)[0]
        p = np.zeros((n, n))
        p[iu, ju] = sol[: len(iu)]
        p = p + p.T - np.diag(np.diag(p))
        k = sol[len(iu):].reshape(m, n)
        k_hist.append(k)
        p_hist.append(p)
        if p_prev is not None and np.linalg.norm(p - p_prev) <= eps:
            return LearningResult(status=LearningStatus.OK, k=k, p=p, iterations=it, rank=rank,
                                  rcond=rcond, n_rows=n_rows, n_unknowns=n_unknowns,
                                  k_history=np.array(k_hist), p_history=np.array(p_hist),
                                  message=f"converged: ‖P_k − P_k−1‖ ≤ {eps:g} after {it}")
        p_prev = p
    return refuse(LearningStatus.NOT_CONVERGED,
                  f"‖P_k − P_k−1‖ > {eps:g} after {max_iterations} iterations",
                  max_iterations, k_hist, p_hist)


# --------------------------------------------------------------------------------------------
# Soft switch (eq 10)


def soft_switch(t: float | np.ndarray, k0: np.ndarray, k1: np.ndarray, *, t_start: float,
                t_switch: float) -> np.ndarray:
    """Eq 10: K' = (K1 + K0)/2 − (K1 − K0)/2 · cos(π τ / T_s), τ = t − t_start clipped to
    [0, T_s] (K0 before t_start, K1 after t_start + T_s). t [s]; returns (..., m, n)."""
    if not (math.isfinite(t_switch) and t_switch > 0):
        raise ValueError(f"t_switch = {t_switch!r} s: must be finite and > 0")
    k0 = np.atleast_2d(np.asarray(k0, dtype=float))
    k1 = np.atleast_2d(np.asarray(k1, dtype=float))
    tau = np.clip(np.asarray(t, dtype=float) - t_start, 0.0, t_switch)
    c = np.cos(np.pi * tau / t_switch)[..., None, None]
    return (k1 + k0) / 2 - (k1 - k0) / 2 * c


# --------------------------------------------------------------------------------------------
# Outer-loop simulation (section 4.1, Figs 4–7)


@dataclasses.dataclass(frozen=True, kw_only=True)
class OuterLoopConfig:
    """Section 4.1 example. Units: amplitude [m], period/duration/steps [s]."""

    human: Operator = Operator.eq2()  # seed 001 eq 2 with the §4.1 gains
    q: tuple[float, ...] = (1.0, 1.0, 1.0)  # diag of Q (eq 27)
    r: float = 0.01  # eq 27
    k0: tuple[float, float, float] = (10.0, 4.0, 0.2)  # eq 31
    amplitude: float = 0.4  # square wave x_d = ±amplitude, +amplitude first
    period: float = 10.0
    duration: float = 15.0
    t_learn: float = 0.5  # data phase
    n_intervals: int = 50  # sampling intervals in the data phase
    step: float = 1e-3  # RK4 step
    t_switch: float = 0.5  # T_s of eq 10
    soft: bool = True  # False: K jumps at t_learn (Fig 7 dashed)
    noise: ExplorationNoise = ExplorationNoise.printed()
    eps: float = 1e-8

    def __post_init__(self) -> None:
        _check_step("OuterLoopConfig.step", self.step, STEP_RANGE)
        for name in ("t_learn", "period", "duration", "t_switch"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"OuterLoopConfig.{name} = {v!r} s: must be finite and > 0")
        sub = self.t_learn / (self.n_intervals * self.step)
        if abs(sub - round(sub)) > 1e-9 or round(sub) < 1:
            raise ValueError(f"OuterLoopConfig.step = {self.step!r} s must divide the sampling "
                             f"interval t_learn/n_intervals = {self.t_learn / self.n_intervals:g} s")
        for name, v in (("period/2", self.period / 2), ("duration", self.duration)):
            ratio = v / self.step
            if abs(ratio - round(ratio)) > 1e-9:
                raise ValueError(f"OuterLoopConfig.step = {self.step!r} s must divide {name} = {v:g} s")

    @property
    def substeps(self) -> int:
        return int(round(self.t_learn / (self.n_intervals * self.step)))

    def matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        a, b = state_space(self.human)
        return a, b, np.diag(self.q), np.array([[self.r]])

    def desired(self, t: np.ndarray) -> np.ndarray:
        """x_d(t) [m]: +amplitude on [0, period/2), −amplitude on [period/2, period), ..."""
        phase = np.mod(np.asarray(t, dtype=float) + 1e-9 * self.step, self.period)
        return np.where(phase < self.period / 2, self.amplitude, -self.amplitude)


@dataclasses.dataclass(frozen=True, kw_only=True)
class OuterTrace:
    """One controller's run on the grid t (T,) [s]: x (T, 3) = [e_p, ė_p, f]; u (T,) = ë_p
    [m/s²] at the grid points; k (T, 3) the gain in use; x_d, x_r (T,) [m]."""

    strategy: Strategy
    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    k: np.ndarray
    x_d: np.ndarray
    x_r: np.ndarray

    def rms(self, t0: float, t1: float) -> tuple[float, float]:
        """(RMS e_p [m], RMS f [N]) over grid points with t0 ≤ t ≤ t1."""
        sel = (self.t >= t0 - 1e-12) & (self.t <= t1 + 1e-12)
        return (float(np.sqrt(np.mean(self.x[sel, 0] ** 2))),
                float(np.sqrt(np.mean(self.x[sel, 2] ** 2))))


@dataclasses.dataclass(frozen=True, kw_only=True)
class OuterLoopResult:
    """status: the learning status (the IOIC trace keeps K_0 when it is not ``ok``).
    rms_full / rms_after_learning: Strategy → (RMS e_p [m], RMS f [N]) over [0, duration] and
    over [t_learn + t_switch, duration]."""

    status: LearningStatus
    optimum: OptimalImpedance
    learning: LearningResult
    data: LearningData
    fic: OuterTrace
    oic: OuterTrace
    ioic: OuterTrace
    rms_full: dict
    rms_after_learning: dict


def _simulate_batch(cfg: OuterLoopConfig, gain_fns, noise_on: np.ndarray) -> tuple:
    """RK4 on a batch of controllers (vectorised over the batch).

    gain_fns[c](t, t_mid) → (T, m, n): the gain at stage times t of the steps with midpoints
    t_mid (a gain jump without soft switch therefore happens between steps); noise_on[c]: v_n
    is added while the step midpoint is < t_learn. The x_d steps (at multiples of period/2,
    grid points) are applied to e_p between steps (x_r is continuous). Schedules and noise
    are evaluated for all stage times up front; the loop only does the 3×3 algebra.
    """
    a, b, _, _ = cfg.matrices()
    n_steps = int(round(cfg.duration / cfg.step))
    h = cfg.step
    t = h * np.arange(n_steps + 1)
    mid = t + h / 2
    xd = cfg.desired(t)
    nb = len(gain_fns)
    k_grid = np.stack([fn(t, mid).reshape(len(t), -1) for fn in gain_fns], axis=1)  # (T, nb, 3)
    k_mid = np.stack([fn(mid, mid).reshape(len(t), -1) for fn in gain_fns], axis=1)
    k_end = np.stack([fn(t + h, mid).reshape(len(t), -1) for fn in gain_fns], axis=1)
    learn = np.where(mid < cfg.t_learn, 1.0, 0.0)[:, None] * np.asarray(noise_on, float)[None]
    v_grid = learn * cfg.noise(t)[:, None]  # (T, nb)
    v_mid = learn * cfg.noise(mid)[:, None]
    v_end = learn * cfg.noise(t + h)[:, None]
    bcol = b[:, 0]
    x = np.zeros((nb, 3))
    x[:, 0] = -xd[0]  # x_r(0) = 0
    xs = np.empty((n_steps + 1, nb, 3))

    def f(xx, kk, vv):
        u = -np.einsum("bj,bj->b", kk, xx) + vv
        return xx @ a.T + u[:, None] * bcol

    for i in range(n_steps):
        xs[i] = x
        k1 = f(x, k_grid[i], v_grid[i])
        k2 = f(x + h / 2 * k1, k_mid[i], v_mid[i])
        k3 = f(x + h / 2 * k2, k_mid[i], v_mid[i])
        k4 = f(x + h * k3, k_end[i], v_end[i])
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        x[:, 0] -= xd[i + 1] - xd[i]  # e_p = x_r − x_d jumps with x_d
    xs[-1] = x
    # u at the grid points: the gain and noise of the step that starts there
    us = -np.einsum("tbj,tbj->tb", k_grid, xs) + v_grid
    return t, xd, xs, us, k_grid


def simulate_outer_loop(cfg: OuterLoopConfig = OuterLoopConfig()) -> OuterLoopResult:
    """FIC, OIC and IOIC on the section 4.1 example (Figs 4–7); see :class:`OuterLoopConfig`."""
    a, b, q, r = cfg.matrices()
    k0 = np.atleast_2d(np.asarray(cfg.k0, dtype=float))
    opt = riccati_optimum(a, b, q, r)
    x0 = np.array([-cfg.desired(np.array(0.0)).item(), 0.0, 0.0])
    data = collect_data(a, b, k0, cfg.noise, x0, duration=cfg.t_learn,
                        n_intervals=cfg.n_intervals, substeps=cfg.substeps)
    learning = policy_iteration(data, k0, q, r, eps=cfg.eps)
    k_target = learning.k if learning.status is LearningStatus.OK else k0

    def const(k):
        return lambda tt, mid: np.broadcast_to(k, (len(tt),) + k.shape)

    def ioic(tt, mid):
        after = (soft_switch(tt, k0, k_target, t_start=cfg.t_learn, t_switch=cfg.t_switch)
                 if cfg.soft else np.broadcast_to(k_target, (len(tt),) + k0.shape))
        return np.where((mid < cfg.t_learn)[:, None, None], k0, after)

    t, xd, xs, us, ks = _simulate_batch(cfg, [const(k0), const(opt.k), ioic],
                                        np.array([0.0, 0.0, 1.0]))
    traces = [OuterTrace(strategy=s, t=t, x=xs[:, c], u=us[:, c], k=ks[:, c], x_d=xd,
                         x_r=xd + xs[:, c, 0])
              for c, s in enumerate((Strategy.FIC, Strategy.OIC, Strategy.IOIC))]
    t_after = cfg.t_learn + cfg.t_switch
    return OuterLoopResult(status=learning.status, optimum=opt, learning=learning, data=data,
                           fic=traces[0], oic=traces[1], ioic=traces[2],
                           rms_full={tr.strategy: tr.rms(0.0, cfg.duration) for tr in traces},
                           rms_after_learning={tr.strategy: tr.rms(t_after, cfg.duration)
                                               for tr in traces})
