"""Local sensitivities of a design's metrics to its continuous keys, in the metric's and the key's units.

Every scalar of the registry evaluation (:func:`hapticopt.analysis.registry.evaluate_all`; a list
metric gives one scalar per entry, ``max_force_N[0]``) against every continuous design key
(``geometry.beta_deg`` …: the numeric, non-integer fields of the design's parameter metadata,
:func:`hapticopt.design.schema.specs`): ∂metric/∂key (e.g. N per deg) and the elasticity
(∂metric/∂key · key/metric, dimensionless: the ranking).

* **jax** where the evaluator is a differentiable closed form: the 3-PRRR statics (seed 002 eq 2, 4, 7,
  14–15) through :func:`hapticopt.analysis.prrr.structure.statics.statics_arrays`, differentiated forward-mode
  with respect to the key values (their unit conversion included).
* **central finite differences** for every other metric. The step is chosen by measurement: each key is
  moved by the relative steps :data:`STEPS` (of |value|, of the key's range where the value is 0), all
  2 × len(STEPS) × n_keys designs evaluated in one call of :func:`registry.evaluate_batch` (the batched
  path at draft fidelity); for each (metric, key) the estimates form a curve that is biased at large
  steps (truncation, ∝ h²) and noisy at small ones (round-off and sampling, ∝ 1/h); the plateau between
  is where neighbouring estimates agree best, and the estimate there is reported with that agreement
  as its relative uncertainty. A metric that is piecewise constant in a key (a sampled workspace) has
  no plateau: status ``not-smooth`` when the best neighbours still disagree by more than
  :data:`PLATEAU_RTOL`, ``zero`` when every estimate is 0.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from hapticopt.analysis import registry
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.registry import metric_unit
from hapticopt.design.errors import InvalidDesign, InvalidInput
from hapticopt.design.schema import specs  # noqa: F401  (re-exported for the tests)
from hapticopt.design.units import from_si, to_si
from hapticopt.optim.problem import Variable, design_at

#: relative FD steps of the measured step sweep (fractions of |key value|)
STEPS: tuple[float, ...] = (1e-3, 1e-4, 1e-5)
#: neighbouring estimates on the plateau agree to this (relative to the estimate's scale)
PLATEAU_RTOL = 1e-3


@dataclass(frozen=True, kw_only=True)
class Key:
    """A continuous design key: TOML name, value and bounds in its unit."""

    key: str
    section: str
    field: str
    unit: str
    value: float
    lower: float
    upper: float

    def variable(self) -> Variable:
        return Variable(key=self.key, section=self.section, field=self.field, unit=self.unit,
                        lower=self.lower, upper=self.upper, start=self.value)


@dataclass(frozen=True, kw_only=True)
class Sensitivity:
    """∂metric/∂key at the design, in the metric's unit per the key's unit."""

    metric: str
    key: str
    metric_unit: str
    key_unit: str
    value: float  # the metric at the design
    key_value: float
    derivative: float | None  # None where not computed (status says why)
    elasticity: float | None  # derivative · key_value / value (None where value is 0)
    method: str  # "jax" or "fd"
    step: float | None  # the FD step [key unit] on the plateau (None for jax)
    uncertainty: float | None  # FD: relative disagreement of the plateau's neighbours
    status: str  # "ok", "zero", "not-smooth", "failed", "bound"

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def continuous_keys(design: Any) -> list[Key]:
    """The design's numeric non-integer keys in section order (``section.key``, value in the key's unit)."""
    out = []
    for section in design.SECTIONS:
        obj = getattr(design, section)
        for fname, spec in specs(type(obj)).items():
            if spec.integer:
                continue
            value = float(f"{from_si(float(getattr(obj, fname)), spec.unit):.15g}")
            out.append(Key(key=f"{section}.{spec.key}", section=section, field=fname, unit=spec.unit, value=value,
                           lower=spec.lo, upper=spec.hi))
    return out


def scalar_metrics(metrics: Mapping[str, Any]) -> dict[str, float]:
    """Every numeric scalar of a metrics dict, list entries as ``name[i]`` (``name[i][j]``); booleans,
    strings and None left out."""
    out: dict[str, float] = {}

    def walk(name: str, value: Any) -> None:
        if isinstance(value, bool) or value is None or isinstance(value, str):
            return
        if isinstance(value, (int, float)):
            out[name] = float(value)
        elif isinstance(value, (list, tuple)):
            for i, v in enumerate(value):
                walk(f"{name}[{i}]", v)

    for name, value in metrics.items():
        walk(name, value)
    return out


def base_name(metric: str) -> str:
    """The registry metric name of a scalar (``max_force_N[0]`` → ``max_force_N``)."""
    return metric.split("[", 1)[0]


# ----------------------------------------------------------------------------- jax (closed forms)
#: statics_arrays output -> (metric name, factor from SI to the metric's unit)
_STATICS = {"condition": ("jacobian_condition", 1.0), "condition_frobenius": ("jacobian_condition_frobenius", 1.0),
            "max_force": ("max_force_N", 1.0), "max_pure_force": ("max_pure_force_N", 1.0),
            "stiffness_limit": ("stiffness_limit_N_per_mm", 1e-3), "effective_mass": ("effective_mass_kg", 1.0)}
#: PrrrParams field -> geometry field; the other statics inputs
_PARAM_FIELDS = ("beta", "d1", "d2", "d3", "d4", "r4", "b5", "stroke")
_OTHER = {"spring": ("actuator", "spring"), "force_limit": ("actuator", "force_limit"),
          "mass": ("end_effector", "mass")}


def jax_statics(design: Any, keys: list[Key]) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """(value, gradient over ``keys`` in key units) of every statics scalar of a 3-PRRR design, by
    forward-mode jax through :func:`statics_arrays` (the evaluator's own closed forms)."""
    from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
    import jax
    import jax.numpy as jnp

    from hapticopt.analysis.prrr.structure.statics import statics_arrays
    from hapticopt.design.prrr.kinematics import PrrrParams

    index = {(k.section, k.field): i for i, k in enumerate(keys)}
    x0 = jnp.asarray([k.value for k in keys])

    def si(x, section: str, fname: str) -> Any:
        i = index.get((section, fname))
        obj = getattr(getattr(design, section), fname)
        return float(obj) if i is None else x[i] * to_si(1.0, keys[i].unit)

    def f(x):
        params = PrrrParams(*(si(x, "geometry", name) for name in _PARAM_FIELDS))
        out = statics_arrays(params, *(si(x, *_OTHER[n]) for n in ("spring", "force_limit", "mass")), xp=jnp)
        return {name: out[name] * scale for name, (_, scale) in _STATICS.items()}

    values = f(x0)
    jac = jax.jacfwd(f)(x0)
    val_out, grad_out = {}, {}
    for name, (metric, _) in _STATICS.items():
        v, g = np.asarray(values[name]), np.asarray(jac[name])
        for idx in np.ndindex(v.shape):
            label = metric + "".join(f"[{i}]" for i in idx)
            val_out[label] = float(v[idx])
            grad_out[label] = g[idx]
    return val_out, grad_out


# ----------------------------------------------------------------------------- finite differences
def _perturbed(design: Any, key: Key, value: float) -> Any | None:
    """``design`` with ``key`` set to ``value`` (key unit); None where the design is invalid there."""
    try:
        return design_at(design, [key.variable()], [value])
    except InvalidDesign:
        return None


def _step(key: Key, rel: float) -> float:
    scale = abs(key.value) if key.value != 0.0 else (
        min(key.upper - key.lower, 1.0) if math.isfinite(key.upper - key.lower) else 1.0)
    return rel * scale


def _evaluate(designs: list[Any], fidelity: Fidelity, only: tuple[str, ...] | None) -> list[dict[str, float]]:
    evs = registry.evaluate_batch(designs, fidelity=fidelity, only=only)
    return [scalar_metrics(ev.metrics()) for ev in evs]


def plateau(estimates: np.ndarray) -> tuple[int, float]:
    """(index, relative disagreement) of the plateau of FD estimates over decreasing steps: the
    neighbouring pair that agrees best, relative to the larger magnitude of the curve."""
    scale = np.nanmax(np.abs(estimates)) if np.any(np.isfinite(estimates)) else np.nan
    diffs = np.abs(np.diff(estimates))
    if not np.isfinite(scale) or scale == 0.0 or not np.any(np.isfinite(diffs)):
        return 0, float("nan")
    k = int(np.nanargmin(diffs))
    return k + 1, float(diffs[k] / scale)


def sensitivities(design: Any, *, fidelity: Fidelity = Fidelity.DRAFT, metrics: list[str] | None = None,
                  keys: list[str] | None = None, steps: tuple[float, ...] = STEPS,
                  use_jax: bool = True, only: tuple[str, ...] | None = None) -> list[Sensitivity]:
    """∂metric/∂key of every scalar metric (or those whose registry name is in ``metrics``) against
    every continuous key (or those named in ``keys``), ranked by |elasticity| (largest first, the
    incomputable last). ``only``: the registry evaluators to run (all by default)."""
    fidelity = Fidelity(fidelity)
    all_keys = continuous_keys(design)
    if keys is not None:
        known = {k.key for k in all_keys}
        unknown = [k for k in keys if k not in known]
        if unknown:
            raise InvalidInput(f"not a continuous key of a {design.device} design: {', '.join(unknown)}")
        all_keys = [k for k in all_keys if k.key in keys]
    base = _evaluate([design], fidelity, only)[0]
    if metrics is not None:
        unknown = sorted(set(metrics) - {base_name(m) for m in base})
        if unknown:
            raise InvalidInput(f"no numeric metric named {', '.join(unknown)} at {fidelity} fidelity")
        base = {m: v for m, v in base.items() if base_name(m) in metrics}
    jax_vals, jax_grads = ({}, {})
    if use_jax and design.device == "prrr" and all_keys:
        jax_vals, jax_grads = jax_statics(design, all_keys)
    fd_metrics = [m for m in base if m not in jax_grads]
    # the step sweep: every key at ±h for every step, in one batch
    plan: list[tuple[int, int, int]] = []  # (key, step, sign) per evaluated design
    designs: list[Any] = []
    if fd_metrics:
        for ki, key in enumerate(all_keys):
            for si, rel in enumerate(steps):
                for sign in (1, -1):
                    d = _perturbed(design, key, key.value + sign * _step(key, rel))
                    if d is not None:
                        plan.append((ki, si, sign))
                        designs.append(d)
    found = _evaluate(designs, fidelity, only) if designs else []
    plus = np.full((len(all_keys), len(steps), len(fd_metrics)), np.nan)
    minus = np.full_like(plus, np.nan)
    col = {m: i for i, m in enumerate(fd_metrics)}
    for (ki, si, sign), vals in zip(plan, found):
        target = plus if sign > 0 else minus
        for m, v in vals.items():
            if m in col:
                target[ki, si, col[m]] = v
    h = np.array([[_step(k, rel) for rel in steps] for k in all_keys])  # (keys, steps)
    with np.errstate(invalid="ignore"):
        est = (plus - minus) / (2.0 * h[..., None])  # (keys, steps, metrics)
    out: list[Sensitivity] = []
    for m, value in base.items():
        for ki, key in enumerate(all_keys):
            if m in jax_grads:
                deriv, method, step, unc = float(jax_grads[m][ki]), "jax", None, None
                status = "ok" if math.isfinite(deriv) else "failed"
                status = "zero" if deriv == 0.0 else status
            else:
                curve = est[ki, :, col[m]]
                method = "fd"
                if not np.any(np.isfinite(curve)):
                    deriv, step, unc, status = None, None, None, "bound" if value == value else "failed"
                elif np.all(curve[np.isfinite(curve)] == 0.0):
                    deriv, step, unc, status = 0.0, float(h[ki, -1]), 0.0, "zero"
                else:
                    k, unc = plateau(curve)
                    deriv, step = float(curve[k]), float(h[ki, k])
                    status = "ok" if unc <= PLATEAU_RTOL else "not-smooth"
                    if not math.isfinite(deriv):
                        deriv, status = None, "failed"
            elast = None
            if deriv is not None and math.isfinite(value) and value != 0.0:
                elast = deriv * key.value / value
            out.append(Sensitivity(metric=m, key=key.key, metric_unit=metric_unit(base_name(m)), key_unit=key.unit,
                                   value=value, key_value=key.value, derivative=deriv, elasticity=elast,
                                   method=method, step=step, uncertainty=unc, status=status))
    out.sort(key=lambda s: -abs(s.elasticity) if s.elasticity is not None and math.isfinite(s.elasticity) else math.inf)
    return out
