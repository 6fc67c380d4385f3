"""Tolerance analysis of the 3-PRRR as manufactured: a spec, Monte Carlo, a linear stack, yield.

**Spec** (TOML; :func:`load_spec`)::

    preset = "ISO2768-m"        # general tolerances, ISO 2768-1 class f, m, c or v (the base)
    distribution = "normal"     # "normal": the tolerance is ±3σ (process capability 1); "uniform": ±t
    [features]                  # per error of design/prrr/tolerance.py ERRORS, or a group of them:
    d3 = 0.02                   #   lengths in mm, angles in deg
    r1_tilt = 0.05              #   "r1_tilt" sets r1_tilt_v and r1_tilt_t; "lengths", "angles": every one
    [keys]                      # per design key (its error): lengths in mm
    "geometry.d4_mm" = 0.01

General tolerances (ISO 2768-1:1989, "General tolerances — Part 1: Tolerances for linear and angular
dimensions without individual tolerance indications", Tables 1 and 3): linear tolerances by nominal
size, angular tolerances by the length of the shorter side of the angle. Each error of the as-built
model takes the class's tolerance at its feature's size (:data:`FEATURES`): a length at its nominal
dimension, an axis direction at the length it is referenced over (R1 in the carriage: the carriage
height; R2 in link 1: d3; R3 in link 2: d4; R3's bore in the platform: b5; the rail: the stroke).

**Monte Carlo**: errors drawn with a seeded ``numpy.random.Generator`` (PCG64) in batches of
:data:`BATCH` devices (the same seed gives the same devices bit for bit, whatever the stopping
point), evaluated by :func:`hapticopt.design.prrr.tolerance.offnominal`; without a fixed sample
count it stops once the standard error of the tracked statistic (the std of cond₂ J at home:
SE(s) = s/√(2(n−1)) for a near-normal sample) is below :data:`TARGET_RSE` of it.

**Linear stack**: the derivative of each output (and of J(p) at every pose) with respect to each error
by central differences of the exact model (step 1 % of σ: truncation ~1e-4 relative). RSS std =
√Σ(g_k σ_k)², worst case = Σ|g_k| t_k; variance shares (g_k σ_k)²/Σ. The constancy deviation is a
norm (not differentiable at zero error): its stack is the linearised model J(p) ≈ J₀ + Σ e_k S_k(p)
sampled with the same errors, and the RSS of ‖J(p) − J₀‖ at the worst pose.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hapticopt.design.errors import InvalidInput
from hapticopt.design.prrr import tolerance as dtol
from hapticopt.design.prrr.params import PrrrDesign
from hapticopt.design.tomlsafe import loads as toml_loads

#: devices per Monte Carlo batch (the seeded draw order)
BATCH = 500
#: the adaptive Monte Carlo stops at this relative standard error of the tracked std
TARGET_RSE = 0.02
#: sample limits of the adaptive run
MIN_SAMPLES, MAX_SAMPLES = 1000, 100_000

#: ISO 2768-1 Table 1, linear dimensions: upper ends of the nominal-size ranges [mm] (from 0.5 mm) and
#: the permissible deviations ± [mm] per class (None: not defined)
ISO_LINEAR_SIZES = (3.0, 6.0, 30.0, 120.0, 400.0, 1000.0, 2000.0, 4000.0)
ISO_LINEAR: dict[str, tuple[float | None, ...]] = {
    "f": (0.05, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5, None),
    "m": (0.1, 0.1, 0.2, 0.3, 0.5, 0.8, 1.2, 2.0),
    "c": (0.2, 0.3, 0.5, 0.8, 1.2, 2.0, 3.0, 4.0),
    "v": (None, 0.5, 1.0, 1.5, 2.5, 4.0, 6.0, 8.0),
}
#: ISO 2768-1 Table 3, angular dimensions: upper ends of the shorter-side ranges [mm] and ± [arc minutes]
ISO_ANGULAR_SIZES = (10.0, 50.0, 120.0, 400.0, math.inf)
ISO_ANGULAR: dict[str, tuple[float, ...]] = {
    "f": (60.0, 30.0, 20.0, 10.0, 5.0),
    "m": (60.0, 30.0, 20.0, 10.0, 5.0),
    "c": (90.0, 60.0, 30.0, 15.0, 10.0),
    "v": (180.0, 120.0, 60.0, 30.0, 20.0),
}
PRESETS = tuple(f"ISO2768-{c}" for c in ISO_LINEAR)


def iso_linear(cls: str, size_mm: float) -> float:
    """ISO 2768-1 linear tolerance ± [mm] of class ``cls`` at nominal size ``size_mm``."""
    for upper, tol in zip(ISO_LINEAR_SIZES, ISO_LINEAR[cls]):
        if size_mm <= upper:
            if tol is None:
                raise InvalidInput(f"ISO 2768-{cls} defines no tolerance for a {size_mm:g} mm size")
            return tol
    raise InvalidInput(f"ISO 2768 covers sizes up to 4000 mm, not {size_mm:g} mm")


def iso_angular(cls: str, shorter_side_mm: float) -> float:
    """ISO 2768-1 angular tolerance ± [deg] of class ``cls`` for a shorter side of ``shorter_side_mm``."""
    for upper, tol in zip(ISO_ANGULAR_SIZES, ISO_ANGULAR[cls]):
        if shorter_side_mm <= upper:
            return tol / 60.0
    raise AssertionError("unreachable")


def _feature_sizes(design: PrrrDesign) -> dict[str, float]:
    """Each error's feature size [mm] for the ISO tables (see the module docstring)."""
    g, s = design.geometry, design.structure
    mm = 1e3
    size = {"rail_tilt_u": g.stroke, "rail_tilt_t": g.stroke, "rail_radial": g.r_p, "rail_tangential": g.r_p,
            "d1": g.d1, "d2": g.d2, "d3": g.d3, "d4": g.d4, "r4": g.r4, "b5": g.b5, "r5": g.r5,
            "r1_tilt_v": s.carriage_height, "r1_tilt_t": s.carriage_height, "r2_tilt_v": g.d3, "r2_tilt_t": g.d3,
            "r3_tilt_v": g.d4, "r3_tilt_t": g.d4, "rp_tilt_v": g.b5, "rp_tilt_t": g.b5}
    return {k: v * mm for k, v in size.items()}


#: design key -> the error it stands for (lengths); the others have no per-key tolerance
KEY_ERRORS = {"geometry.d1_mm": "d1", "geometry.d2_mm": "d2", "geometry.d3_mm": "d3", "geometry.d4_mm": "d4",
              "geometry.r4_mm": "r4", "geometry.b5_mm": "b5", "geometry.r_p_mm": "rail_radial"}


@dataclass(frozen=True, kw_only=True)
class Spec:
    """Tolerances ± per error (SI: m or rad), and how errors are distributed."""

    name: str
    tolerance: np.ndarray  # (N_ERRORS,) ± t, the same for every leg
    distribution: str = "normal"
    source: dict[str, str] = field(default_factory=dict)  # error -> where its tolerance came from

    @property
    def sigma(self) -> np.ndarray:
        """Standard deviation per error: t/3 (normal) or t/√3 (uniform on ±t)."""
        return self.tolerance / (3.0 if self.distribution == "normal" else math.sqrt(3.0))

    def as_dict(self) -> dict[str, Any]:
        """± per error in mm or deg (JSON-ready)."""
        return {"name": self.name, "distribution": self.distribution,
                "tolerance": {e: _to_user(e, float(t)) for e, t in zip(dtol.ERRORS, self.tolerance)},
                "units": {e: ("deg" if a else "mm") for e, a in zip(dtol.ERRORS, dtol.ANGULAR)},
                "source": self.source}


def _to_user(error: str, value: float) -> float:
    return math.degrees(value) if dtol.ANGULAR[dtol.error_index(error)] else value * 1e3


def _from_user(error: str, value: float) -> float:
    return math.radians(value) if dtol.ANGULAR[dtol.error_index(error)] else value * 1e-3


def iso_spec(design: PrrrDesign, cls: str) -> Spec:
    """The ISO 2768-1 general tolerances of class ``cls`` (f, m, c, v) for every error of ``design``."""
    if cls not in ISO_LINEAR:
        raise InvalidInput(f"ISO 2768 class {cls!r} is not one of {', '.join(ISO_LINEAR)}")
    sizes = _feature_sizes(design)
    tol = np.array([math.radians(iso_angular(cls, sizes[e])) if ang else iso_linear(cls, sizes[e]) * 1e-3
                    for e, ang in zip(dtol.ERRORS, dtol.ANGULAR)])
    src = {e: f"ISO 2768-{cls} {'angular, shorter side' if a else 'linear, size'} {sizes[e]:.4g} mm"
           for e, a in zip(dtol.ERRORS, dtol.ANGULAR)}
    return Spec(name=f"ISO2768-{cls}", tolerance=tol, source=src)


def spec_from_dict(design: PrrrDesign, data: Mapping[str, Any], *, source: str = "spec") -> Spec:
    """A :class:`Spec` from the TOML table (module docstring); one :class:`InvalidInput` line otherwise."""
    allowed = {"preset", "distribution", "features", "keys"}
    for k in data:
        if k not in allowed:
            raise InvalidInput(f"{source}: {k} is not a known key: allowed {', '.join(sorted(allowed))}")
    preset = data.get("preset", "ISO2768-m")
    if preset not in PRESETS:
        raise InvalidInput(f"{source}: preset = {preset!r} is not one of {', '.join(PRESETS)}")
    base = iso_spec(design, preset.rsplit("-", 1)[1])
    tol, src = base.tolerance.copy(), dict(base.source)
    dist = data.get("distribution", "normal")
    if dist not in ("normal", "uniform"):
        raise InvalidInput(f"{source}: distribution = {dist!r} must be \"normal\" or \"uniform\"")

    def put(error: str, value: Any, where: str) -> None:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            raise InvalidInput(f"{where} = {value!r} must be a finite number ≥ 0 (mm or deg)")
        tol[dtol.error_index(error)] = _from_user(error, float(value))
        src[error] = where

    for name, value in dict(data.get("features", {})).items():
        where = f"{source}: features.{name}"
        if name in dtol.ERRORS:
            targets = [name]
        elif name == "lengths":
            targets = [e for e, a in zip(dtol.ERRORS, dtol.ANGULAR) if not a]
        elif name == "angles":
            targets = [e for e, a in zip(dtol.ERRORS, dtol.ANGULAR) if a]
        else:
            targets = [e for e in dtol.ERRORS if e.startswith(name + "_")]
        if not targets:
            raise InvalidInput(f"{where} is not an error or a group: allowed {', '.join(dtol.ERRORS)}, lengths, "
                               "angles, or a prefix such as r1_tilt")
        for e in targets:
            put(e, value, where)
    for key, value in dict(data.get("keys", {})).items():
        if key not in KEY_ERRORS:
            raise InvalidInput(f"{source}: keys.{key} has no tolerance of its own: allowed {', '.join(KEY_ERRORS)}")
        put(KEY_ERRORS[key], value, f"{source}: keys.{key}")
    return Spec(name=str(data.get("name", preset if len(data) <= 1 else source)), tolerance=tol,
                distribution=dist, source=src)


def load_spec(design: PrrrDesign, text: str) -> Spec:
    """A preset name (``ISO2768-m``) or the path of a spec TOML file."""
    if text in PRESETS:
        return iso_spec(design, text.rsplit("-", 1)[1])
    path = Path(text)
    try:
        raw = path.read_text()
    except OSError as exc:
        raise InvalidInput(f"--spec {text}: neither a preset ({', '.join(PRESETS)}) nor a readable file "
                           f"({exc.strerror})") from None
    return spec_from_dict(design, toml_loads(raw, source=str(path)), source=str(path))


# --------------------------------------------------------------------------------- Monte Carlo
def draw(spec: Spec, rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` devices' errors (n, 3, N_ERRORS) [SI]."""
    if spec.distribution == "normal":
        z = rng.standard_normal((n, 3, dtol.N_ERRORS))
    else:
        z = rng.uniform(-math.sqrt(3.0), math.sqrt(3.0), (n, 3, dtol.N_ERRORS))
    return z * spec.sigma


#: yield constraints by default: cond(J) variation ≤ 1 % over the workspace, and the required cylinder
#: (every pose of the φ140 × 89 mm grid still reached within the stroke)
DEFAULT_REQUIREMENTS = ("cond_spread<=0.01", "margin>=0")


def parse_requirement(text: str) -> tuple[str, str, float]:
    """``name<=value`` / ``name>=value`` over an :class:`Offnominal` field."""
    for op in ("<=", ">="):
        if op in text:
            name, _, value = text.partition(op)
            name = name.strip()
            if name not in dtol.Offnominal._fields:
                raise InvalidInput(f"requirement {text!r}: {name!r} is not one of {', '.join(dtol.Offnominal._fields)}")
            try:
                return name, op, float(value)
            except ValueError:
                raise InvalidInput(f"requirement {text!r}: {value.strip()!r} is not a number") from None
    raise InvalidInput(f"requirement {text!r} must read name<=value or name>=value")


@dataclass(frozen=True, kw_only=True)
class MonteCarlo:
    samples: int
    seed: int
    results: dtol.Offnominal  # per device
    errors_sigma: np.ndarray  # spec.sigma
    stopped: str  # "fixed" or "converged" or "limit"

    def fields(self) -> dict[str, np.ndarray]:
        """The numeric per-device results over the devices whose IK closed at every pose."""
        ok = self.results.converged
        return {name: v[ok] for name, v in self.results._asdict().items() if name != "converged"}

    @property
    def converged(self) -> int:
        """Devices whose IK closed at every pose (the others reach no solution at some pose)."""
        return int(np.sum(self.results.converged))

    def percentiles(self, qs=(1, 5, 50, 95, 99)) -> dict[str, dict[str, float]]:
        return {name: {f"p{q}": float(np.percentile(v, q)) if len(v) else math.nan for q in qs}
                for name, v in self.fields().items()}

    def stats(self) -> dict[str, dict[str, float]]:
        out = {}
        for name, v in self.fields().items():
            n = len(v)
            if n < 2:
                out[name] = dict.fromkeys(("mean", "std", "std_se", "mean_se", "min", "max"), math.nan)
                continue
            s = float(np.std(v, ddof=1))
            out[name] = {"mean": float(np.mean(v)), "std": s, "std_se": s / math.sqrt(2.0 * (n - 1)),
                         "mean_se": s / math.sqrt(n), "min": float(np.min(v)), "max": float(np.max(v))}
        return out

    def yield_of(self, requirements) -> dict[str, Any]:
        ok = self.results.converged.copy()  # a device that does not reach a pose fails every requirement
        for name, op, value in requirements:
            v = getattr(self.results, name)
            ok &= (v <= value) if op == "<=" else (v >= value)
        n, y = self.samples, float(np.mean(ok))
        z = 1.959964  # Wilson score interval, 95 % (stays inside [0, 1] and is not empty at 0 or n passes)
        centre = (y + z * z / (2 * n)) / (1 + z * z / n)
        half = z * math.sqrt(y * (1 - y) / n + z * z / (4 * n * n)) / (1 + z * z / n)
        return {"yield": y, "yield_ci95": [max(0.0, centre - half), min(1.0, centre + half)],
                "requirements": [f"{n_}{op}{v:g}" for n_, op, v in requirements]}


def monte_carlo(design: PrrrDesign, spec: Spec, *, samples: int | None = None, seed: int = 0,
                poses: np.ndarray | None = None, track: str = "cond_home") -> MonteCarlo:
    """Monte Carlo of ``samples`` devices, or adaptive (module docstring) when ``samples`` is None."""
    rng = np.random.default_rng(seed)
    parts: list[dtol.Offnominal] = []
    n = 0
    stopped = "fixed"
    while True:
        size = BATCH if samples is None else min(BATCH, samples - n)
        if size <= 0:
            break
        parts.append(dtol.offnominal(design, draw(spec, rng, size), poses))
        n += size
        if samples is None and n >= MIN_SAMPLES:
            v = np.concatenate([getattr(p, track) for p in parts])
            v = v[np.isfinite(v)]
            s = float(np.std(v, ddof=1)) if len(v) > 1 else 0.0
            if s == 0.0 or s / math.sqrt(2.0 * (n - 1)) <= TARGET_RSE * s:
                stopped = "converged"
                break
            if n >= MAX_SAMPLES:
                stopped = "limit"
                break
    res = dtol.Offnominal(*(np.concatenate(c) for c in zip(*parts)))
    return MonteCarlo(samples=n, seed=seed, results=res, errors_sigma=spec.sigma, stopped=stopped)


# --------------------------------------------------------------------------------- linear stack
#: outputs whose linear stack is a gradient (smooth at zero error)
SMOOTH = ("cond_home", "cond_home_frobenius")


@dataclass(frozen=True, kw_only=True)
class LinearStack:
    nominal: dict[str, float]
    gradient: dict[str, np.ndarray]  # output -> (3 legs, N_ERRORS) per SI error
    rss_std: dict[str, float]
    worst_case: dict[str, float]
    shares: dict[str, dict[str, float]]  # output -> error name (legs summed) -> variance share
    constancy_rss: float  # √Σ σ²‖S_k(p)‖² / ‖J₀‖ at the worst pose
    constancy_worst: float  # max_p Σ t_k ‖S_k(p)‖ / ‖J₀‖ (triangle inequality: a bound)
    constancy_shares: dict[str, float]
    sens_j: np.ndarray  # (3 legs, N_ERRORS, P, 3, 3) ∂J(p)/∂e


def _state_j(design: PrrrDesign, errors: np.ndarray, poses: np.ndarray) -> np.ndarray:
    dev = dtol.build(design, errors)
    return dtol.jacobian(dev, dtol.inverse_kinematics(design, dev, poses))


def linear_stack(design: PrrrDesign, spec: Spec, poses: np.ndarray | None = None) -> LinearStack:
    """First-order stack of every error (central differences of the exact model, step σ/100)."""
    poses = dtol.pose_grid() if poses is None else poses
    k = 3 * dtol.N_ERRORS
    h = np.tile(np.maximum(spec.sigma, 1e-12) * 1e-2, 3)  # (k,)
    e = np.zeros((2 * k, 3, dtol.N_ERRORS))
    flat = e.reshape(2 * k, k)
    flat[np.arange(k), np.arange(k)] = h
    flat[k + np.arange(k), np.arange(k)] = -h
    nominal = dtol.offnominal(design, dtol.zero_errors(1), poses)
    j = _state_j(design, e, poses)  # (2k, P, 3, 3)
    home = dtol.home_index(poses)
    out = {"cond_home": dtol.cond2(j[:, home]), "cond_home_frobenius": dtol.cond_frobenius(j[:, home])}
    sens_j = ((j[:k] - j[k:]) / (2.0 * h)[:, None, None, None]).reshape(3, dtol.N_ERRORS, len(poses), 3, 3)
    sigma = np.tile(spec.sigma, 3).reshape(3, dtol.N_ERRORS)
    tol = np.tile(spec.tolerance, 3).reshape(3, dtol.N_ERRORS)
    grad, rss, worst, shares = {}, {}, {}, {}
    for name in SMOOTH:
        v = out[name]
        g = ((v[:k] - v[k:]) / (2.0 * h)).reshape(3, dtol.N_ERRORS)
        grad[name] = g
        var = (g * sigma) ** 2
        rss[name] = float(math.sqrt(var.sum()))
        worst[name] = float(np.sum(np.abs(g) * tol))
        shares[name] = _shares(var)
    from hapticopt.design.prrr import kinematics as kin
    j0 = np.asarray(kin.jacobian(design.geometry.beta, xp=np))
    n0 = float(np.linalg.norm(j0))
    norms = np.linalg.norm(sens_j, axis=(-2, -1))  # (3, E, P)
    var_p = np.sum((norms * sigma[..., None]) ** 2, axis=(0, 1))  # (P,)
    worst_pose = int(np.argmax(var_p))
    return LinearStack(nominal={f: float(getattr(nominal, f)[0]) for f in dtol.Offnominal._fields},
                       gradient=grad, rss_std=rss, worst_case=worst, shares=shares,
                       constancy_rss=float(math.sqrt(var_p[worst_pose])) / n0,
                       constancy_worst=float(np.max(np.sum(norms * tol[..., None], axis=(0, 1)))) / n0,
                       constancy_shares=_shares((norms[..., worst_pose] * sigma) ** 2), sens_j=sens_j)


def _shares(var: np.ndarray) -> dict[str, float]:
    """Variance shares per error name (the three legs summed), largest first."""
    total = float(var.sum())
    per = var.sum(axis=0) / total if total > 0 else np.zeros(dtol.N_ERRORS)
    return dict(sorted(((e, float(s)) for e, s in zip(dtol.ERRORS, per)), key=lambda kv: -kv[1]))


def linearised_constancy(design: PrrrDesign, stack: LinearStack, errors: np.ndarray) -> np.ndarray:
    """The constancy deviation of the linearised model J(p) ≈ J₀ + Σ e_k S_k(p) for ``errors`` (n, 3, E)."""
    from hapticopt.design.prrr import kinematics as kin
    j0 = np.asarray(kin.jacobian(design.geometry.beta, xp=np))
    s = stack.sens_j.reshape(3 * dtol.N_ERRORS, -1)
    dj = (errors.reshape(len(errors), -1) @ s).reshape(len(errors), -1, 9)
    return np.max(np.linalg.norm(dj, axis=-1), axis=-1) / np.linalg.norm(j0)
