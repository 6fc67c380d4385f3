"""Which evaluators apply to which device, in report order; the one loop that runs them.

Each evaluator module exposes ``evaluate(design, *, fidelity) -> Result`` where ``Result`` is
frozen and has ``metrics() -> dict`` (engineering units, unit in the name), ``status`` and
``message``. Pictures are not drawn by evaluators: an entry names a function of its device's
``plots`` module (``"module:function"``, called as ``fn(design, result, out_dir)``). Modules are
imported lazily so that a CLI call pays only for what it runs.

The one evaluator convention (docs/architecture.md, "One evaluator convention"): ``evaluate(design, *, fidelity)``,
plus two keywords an entry declares, never found by inspecting signatures:

* ``shared=``: the steps several evaluators of one device take for a design (the 3-PRRR's part tables,
  envelope and reach core: :data:`SHARED_STEPS`), made once per :func:`evaluate_all` call and handed to
  the evaluators whose entry says ``shared=True``;
* ``compute=``: the caller's :class:`~hapticopt.analysis.compute.Compute` (route and kernel threads),
  handed to the evaluators whose entry says ``takes_compute=True`` (those with more than one route).

A device may have a batch evaluator (:data:`BATCHED`): :func:`evaluate_batch` sends a list of its
designs there at the fidelity it serves, with equal results.

One failure policy for every caller (``hapticopt evaluate``, the optimiser's design points and
the pipeline): an evaluator that raises is reported as :attr:`Status.FAILED` with the
exception's type, message and location (file:line); the other evaluators still run.
"""

from __future__ import annotations

import importlib
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any

import numpy as np

from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.design.errors import InvalidDesign, InvalidInput
from hapticopt.design import offscreen
from hapticopt.design.paths import check_name, inside


#: every fidelity level; a metric reported only at some levels names them
ALL_LEVELS: tuple[Fidelity, ...] = tuple(Fidelity)


@dataclass(frozen=True)
class MetricDoc:
    """What a metric means (the glossary's one source): its name (unit in the suffix), a one-line
    description, and the fidelity levels at which its evaluator reports it."""

    name: str
    description: str
    fidelities: tuple[Fidelity, ...] = ALL_LEVELS

    @property
    def unit(self) -> str:
        return metric_unit(self.name)


def _m(name: str, description: str, *levels: str) -> MetricDoc:
    return MetricDoc(name, description, tuple(Fidelity(f) for f in levels) if levels else ALL_LEVELS)


@dataclass(frozen=True, kw_only=True)
class EvaluatorEntry:
    name: str  # short name used in reports and timings
    module: str  # dotted module path exposing evaluate()
    plot: str | None = None  # "module:function" drawing this evaluator's result, or None
    fidelity: str = ""  # what the fidelity levels change (the glossary's "fidelity" column)
    slow_at: tuple[str, ...] = ()  # fidelities at which it takes seconds (the pipeline runs it in a second process)
    metrics: tuple[MetricDoc, ...] = ()  # every metric it can report (tests/analysis/test_registry.py checks)
    shared: bool = False  # its evaluate() takes ``shared=``, the call's SHARED_STEPS of the design
    takes_compute: bool = False  # its evaluate() takes ``compute=``, the caller's route (more than one route)
    #: fidelities at which it runs only when the call names it in ``only`` (an effect the caller asks for:
    #: at draft the strength check costs ~10x the rest of a draft evaluation, so the optimiser's draft loop
    #: and a draft sweep do not pay for it unless a metric of it is wanted)
    on_request_at: tuple[str, ...] = ()

    def load(self) -> Any:
        return importlib.import_module(self.module)

    def plotter(self) -> Any:
        if self.plot is None:
            return None
        module, _, function = self.plot.partition(":")
        return getattr(importlib.import_module(module), function)


_A = "hapticopt.analysis."
_FINE = ("fine",)
_STD_FINE = ("standard", "fine")

#: device -> evaluators in report order. Add a line here to plug an evaluator into
#: ``hapticopt evaluate``, the optimiser and the pipeline; describe its metrics in the same entry
#: (``hapticopt metrics`` and docs/metrics.md are generated from them).
EVALUATORS: dict[str, tuple[EvaluatorEntry, ...]] = {
    "prrr": (
        EvaluatorEntry(name="statics", module=_A + "prrr.structure.statics", shared=True,
                       fidelity="closed forms (constant Jacobian): the same at every level",
                       metrics=(
            _m("jacobian_condition", "2-norm condition number of the constant Jacobian J (1 = isotropic; seed 002 eq 2)"),
            _m("jacobian_condition_frobenius", "Frobenius-norm condition number of J, normalised (smooth: the optimiser's form)"),
            _m("max_force_N", "largest end-effector force per axis x, y, z with the other components free (actuator force limit through J⁻ᵀ)"),
            _m("max_pure_force_N", "largest force along each axis alone (x, y, z) that no actuator exceeds"),
            _m("stiffness_limit_N_per_mm", "largest renderable stiffness per axis x, y, z from the SEA springs, diag J⁻ᵀ(kI)J⁻¹ (seed 002 eq 14–15)"),
            _m("effective_mass_kg", "3×3 equivalent mass matrix of the moving parts at the end-effector (seed 002 eq 7)"),
        )),
        EvaluatorEntry(name="structural_stiffness", module=_A + "prrr.structure.stiffness", takes_compute=True,
                       plot=_A + "prrr.plots:structure_plots",
                       fidelity="draft/standard: Timoshenko frame model; fine: also the solid FEA of the CAD (tens of seconds)",
                       slow_at=_FINE,
                       metrics=(
            _m("structural_stiffness_N_per_mm", "Cartesian stiffness x, y, z of the linkage for a force applied at the load height above the end-effector, sliders locked (seed 002 Table 3)"),
            _m("elastic_centre_mm", "height above the end-effector where a lateral force and the platform rotation decouple"),
            _m("structural_stiffness_at_elastic_centre_N_per_mm", "Cartesian stiffness x, y, z for a force applied at the elastic centre"),
            _m("structural_load_height_mm", "height of the load point above the end-effector (seed 002: 58 mm)"),
            _m("structural_condition", "condition estimate of the frame stiffness matrix (large: singular or ill-conditioned)"),
            _m("structural_stiffness_fea_bonded_N_per_mm", "stiffness x, y, z at the load point from the solid FEA of the CAD with bonded pins", *_FINE),
            _m("structural_stiffness_frame_bonded_N_per_mm", "the frame model's stiffness with bonded joints at the CAD's elbow branch (the model the FEA checks)", *_FINE),
            _m("structural_fea_dofs", "degrees of freedom of the solid FEA mesh", *_FINE),
            _m("structural_fea_wall_s", "wall time of the solid FEA", *_FINE),
            _m("structural_fea_max_von_mises_MPa_per_N", "largest von Mises stress of the FEA per newton of lateral (x) load", *_FINE),
            _m("structural_fea_max_von_mises_at_mm", "where that stress occurs (x, y, z)", *_FINE),
        )),
        EvaluatorEntry(name="workspace", module=_A + "prrr.geometry.workspace", plot=_A + "prrr.plots:workspace_plots",
                       shared=True,
                       fidelity="angular quadrature and radial sampling grow with the level; fine adds the Jacobian "
                                "constancy check and the manifold3d interference reference",
                       metrics=(
            _m("workspace_volume_mm3", "volume reached by every leg within the slider stroke (reach ∩ stroke)"),
            _m("workspace_cylinder_diameter_mm", "diameter of the largest-volume vertical cylinder about z inside the workspace"),
            _m("workspace_cylinder_height_mm", "height of that cylinder"),
            _m("workspace_height_at_diameter_mm", "height of a cylinder of the required diameter (0: it does not fit)"),
            _m("workspace_required_diameter_mm", "required workspace diameter (design input; seed 002: 140 mm)"),
            _m("footprint_diameter_mm", "diameter of the device body in xy: fixed parts and carriages (seed 002's device size)"),
            _m("link_sweep_diameter_mm", "diameter swept by the links over the reach region (CAD's elbow branch)"),
            _m("device_diameter_mm", "diameter of the whole device in xy: the body (footprint) or the links' sweep, whichever is larger"),
            _m("workspace_footprint_ratio", "workspace cylinder diameter over footprint diameter (seed 002 Table 1: 140/260)"),
            _m("jacobian_condition_deviation", "largest relative deviation of the finite-difference cond₂(J) over the workspace from the constant one", *_FINE),
            _m("workspace_interference_removed_fraction", "share of the sampled workspace volume lost to part collisions (manifold3d meshes)", *_FINE),
            _m("workspace_free_volume_mm3", "workspace volume after removing the colliding share", *_FINE),
        )),
        EvaluatorEntry(name="interference", module=_A + "prrr.collision.interference", shared=True, takes_compute=True,
                       fidelity="the same convex-primitive model at every level (conservative against manifold3d)",
                       metrics=(
            _m("interference_removed_fraction", "share of the sampled workspace volume whose poses make two parts collide (0 … 1)"),
            _m("interference_overlap_fraction", "continuous companion: poses weighted by their deepest overlap up to 1 mm (0 … 1)"),
        )),
        EvaluatorEntry(name="free_workspace", module=_A + "prrr.collision.free_workspace", shared=True, takes_compute=True,
                       fidelity="draft/standard: sampling with the fast separating-axis checker; fine: manifold3d meshes (the reference)",
                       metrics=(
            _m("workspace_free_radius_mm", "radius about z within which every column is reached and collision-free"),
            _m("workspace_free_cylinder_diameter_mm", "diameter of the largest-volume collision-free vertical cylinder about z"),
            _m("workspace_free_cylinder_height_mm", "height of that cylinder"),
            _m("workspace_free_height_at_diameter_mm", "height of the collision-free cylinder of the required diameter (0: not free)"),
            _m("workspace_free_footprint_ratio", "collision-free cylinder diameter over footprint diameter (seed 002's design goal)"),
            _m("workspace_free_device_ratio", "collision-free cylinder diameter over the whole device's diameter (device_diameter_mm: body or link sweep)"),
        )),
        EvaluatorEntry(name="device_size", module=_A + "prrr.geometry.device_size", shared=True,
                       fidelity="analytic mass model of the part tables: the same at every level",
                       metrics=(
            _m("device_mass_kg", "mass of every part (seed 002 Table 1: 4.4 kg)"),
            _m("device_mass_sea_modules_kg", "mass of the three SEA modules (motor with belt, ball screw, spring housing)"),
            _m("device_mass_links_kg", "mass of the moving links and the platform"),
            _m("device_mass_frame_kg", "mass of the base plate, rails and carriages"),
            _m("device_height_mm", "height from the base plate's bottom to the rail tops (seed 002 Table 1: 231 mm)"),
        )),
        EvaluatorEntry(name="joint_limits", module=_A + "prrr.geometry.joint_limits",
                       fidelity="fine also turns each joint until its parts meet (manifold3d stops)",
                       metrics=(
            _m("joint_elbow_limit_deg", "largest elbow angle |θ2| kept a joint-boss radius from the folded singularity"),
            _m("joint_limit_margin_deg", "smallest margin of the joint ranges used over the free cylinder to their limits (negative: a limit cuts it)"),
            _m("joint_range_r1_deg", "range [min, max] joint R1 sweeps over the collision-free cylinder (every leg alike)"),
            _m("joint_range_r2_deg", "range [min, max] joint R2 (elbow) sweeps over the collision-free cylinder"),
            _m("joint_range_r3_deg", "range [min, max] joint R3 sweeps over the collision-free cylinder"),
        )),
        EvaluatorEntry(name="stability", module=_A + "prrr.loop.stability", shared=True,
                       fidelity="closed forms: the same at every level",
                       metrics=(
            _m("force_loop_bandwidth_Hz", "−3 dB bandwidth of the SEA force loop with the output locked (seed 002 eq 8; 38.5 Hz at K_p = 45)"),
            _m("closed_loop_stiffness_limit_N_per_mm", "largest stable virtual stiffness x, y, z of the continuous closed loop at the force gain, zero virtual damping (Routh–Hurwitz)"),
        )),
        EvaluatorEntry(name="strength", module=_A + "prrr.structure.strength", takes_compute=True,
                       fidelity="draft (only when asked for by name, e.g. --only strength): frame stresses at the home pose; standard: the worst of 9 workspace poses; fine: also the solid FEA's stress per part for its 1 N x case",
                       slow_at=_FINE, on_request_at=("draft",),
                       metrics=(
            _m("safety_factor_yield", "material yield strength over the largest von Mises stress of any part (frame model: members and pin necks) at the rated force along ±x, ±y, ±z with own weight, worst pose (higher is better)"),
            _m("safety_factor_fatigue", "material fatigue strength (S-N at 1e7 or the library's count) over the stress amplitude of the rated force fully reversed, 1e7 cycles assumed (higher is better)"),
            _m("strength_max_von_mises_MPa", "the largest von Mises stress of any part over the poses and load cases"),
            _m("strength_governing_part", "the part with the smallest safety factor (pin_r3_2: the R3 pin of leg 2)"),
            _m("strength_governing_pose_mm", "end-effector position x, y, z where the governing stress occurs"),
            _m("strength_governing_load", "the load case of the governing stress (rated force direction and magnitude, with own weight)"),
            _m("strength_rated_force_N", "the rated force per axis x, y, z applied (the actuators' largest end-effector force, seed 002 Table 1)"),
            _m("strength_material", "the mechanism's material (design/materials.toml)"),
            _m("safety_factor_yield_per_part", "yield safety factor of every part (links, carriages, platform, pins)"),
            _m("strength_poses_unreachable", "poses of the strength check's set the design cannot reach (skipped)"),
            _m("strength_fea_max_von_mises_MPa_per_N_per_part", "largest element von Mises stress per part of the solid FEA (bonded pins, home, 1 N x at the load height)", *_FINE),
            _m("strength_frame_max_von_mises_MPa_per_N_per_part", "the frame model's (bonded joints, CAD elbow branch) stress per part for the FEA's load case", *_FINE),
            _m("strength_fea_governing_part", "the part where the FEA's stress is largest", *_FINE),
            _m("strength_frame_vs_fea_pct", "frame stress over FEA stress − 1 for the FEA's governing part", *_FINE),
        )),
    ),
    "master": (
        EvaluatorEntry(name="workspace", module=_A + "master.workspace", plot=_A + "master.plots:workspace_plots",
                       fidelity="Gauss points, box samples and search cells grow with the level",
                       metrics=(
            _m("workspace_volume_mm3", "volume of the joint-range workspace (change of variables, Gauss–Legendre)"),
            _m("workspace_coverage", "fraction of the required box covered by the workspace, box placed where it covers most (0 … 1)"),
            _m("workspace_required_box_mm", "edge lengths x, y, z of the required box (design input)"),
            _m("workspace_centroid_mm", "centroid x, y, z of the workspace"),
            _m("workspace_box_centre_mm", "centre x, y, z of the best-placed required box"),
            _m("global_conditioning_index", "workspace mean of 1/κ(J) (1 = isotropic everywhere)"),
            _m("jacobian_condition_min", "smallest condition number κ(J) over the workspace"),
            _m("jacobian_condition_max", "largest condition number κ(J) over the workspace"),
        )),
        EvaluatorEntry(name="balance", module=_A + "master.balance", plot=_A + "master.plots:balance_plots",
                       fidelity="pose grid, zoom levels and force directions grow with the level",
                       metrics=(
            _m("max_unbalance_force_N", "largest gravity force at the handle over the workspace with the motors off (seed 003 eq 5)"),
            _m("unbalance_radius_mm", "largest CoM offset whose unbalance force stays below 0.1 N everywhere (seed 003 eq 12)"),
            _m("com_offset_mm", "offset (P_x, P_z) of the arm's centre of mass from the balanced point"),
            _m("com_inside_unbalance_radius", "whether the CoM offset lies inside the unbalance region"),
            _m("unbalance_ellipse_axes_mm", "semi-axes of the exact unbalance region (an ellipse in P_x, P_z)"),
            _m("unbalance_ellipse_overlap_pct", "overlap of the exact region with seed 003's circle of the unbalance radius"),
            _m("unbalance_ellipse_fit_mm", "semi-axes of the ellipse fitted to the sampled region boundary"),
            _m("unbalance_ellipse_tilt_deg", "tilt of the fitted ellipse"),
            _m("balancing_counterweights_kg", "counterweight masses (upper, forearm) that would put the CoM on the balanced point"),
            _m("moving_mass_kg", "mass M of the moving arm (seed 003: 1.30 kg)"),
        )),
        EvaluatorEntry(name="transparency", module=_A + "master.transparency",
                       plot=_A + "master.plots:transparency_plots",
                       fidelity="draft: the reference pose only; standard/fine: also the worst case over a joint grid",
                       metrics=(
            _m("transparency_bandwidth_Hz", "first frequency where |F_H/F_D| leaves 0 ± 3 dB, along x and z at the reference pose (seed 003 eq 13–15)"),
            _m("transparency_bandwidth_min_Hz", "the lower of the two transparency bandwidths"),
            _m("apparent_mass_kg", "apparent mass of the arm along x and z at the reference pose"),
            _m("transparency_bandwidth_worst_Hz", "lowest transparency bandwidth x, z over the workspace grid", *_STD_FINE),
        )),
    ),
    "handle": (
        EvaluatorEntry(name="stability", module=_A + "handle.stability",
                       fidelity="closed forms and the exact sampled loop: the same at every level",
                       metrics=(
            _m("max_stable_stiffness_N_per_mm", "largest stable wall stiffness K_e of the exact sampled loop (zero-order hold)"),
            _m("pade_stable_stiffness_N_per_mm", "the same limit with seed 000's Padé hold (eq 15–19)"),
            _m("pade_minus_exact_pct", "Padé limit relative to the exact one"),
            _m("eq19_stable_stiffness_N_per_mm", "seed 000's eq 19 closed form of the limit"),
            _m("wall_stable", "whether the described wall (K_e, B_e) is stable with the hand"),
            _m("wall_margin", "stability margin of the described wall: slowest modal decay rate over the mechanical rate b/m (> 0 stable)"),
            _m("eq22_operator_stiffness_N_per_mm", "seed 000's eq 22 critical operator stiffness for the described wall"),
            _m("critical_operator_stiffness_N_per_mm", "the exact-hold critical operator stiffness (NaN if none up to 10⁶ N/mm)"),
            _m("max_stable_stiffness_vs_period_N_per_mm", "stiffness limit at each controller period of sweep_period_ms"),
            _m("sweep_period_ms", "controller periods of that sweep"),
            _m("max_stable_stiffness_vs_wall_damping_N_per_mm", "stiffness limit at each wall damping of sweep_wall_damping_Ns_per_m"),
            _m("sweep_wall_damping_Ns_per_m", "wall dampings of that sweep"),
            _m("max_stable_stiffness_vs_operator_stiffness_N_per_mm", "stiffness limit at each operator stiffness of sweep_operator_stiffness_N_per_mm"),
            _m("sweep_operator_stiffness_N_per_mm", "operator stiffnesses of that sweep"),
        )),
        EvaluatorEntry(name="upsampling", module=_A + "handle.upsampled",
                       fidelity="lifted multi-rate loop, exact: the same at every level",
                       metrics=(
            _m("upsampling", "upsampling factor L = l2/l1 of the firmware"),
            _m("max_stable_stiffness_none_N_per_mm", "largest stable wall stiffness without upsampling (lifted loop)"),
            _m("max_stable_stiffness_as_printed_N_per_mm", "the limit with seed 000's eq 23 spline as printed"),
            _m("upsampling_as_printed_vs_none_pct", "as-printed limit relative to no upsampling"),
            _m("max_stable_stiffness_as_intended_N_per_mm", "the limit with eq 23 as intended (update point to predicted point)"),
            _m("upsampling_as_intended_vs_none_pct", "as-intended limit relative to no upsampling"),
            _m("upsampling_default_variant", "the variant the firmware uses"),
        )),
        EvaluatorEntry(name="zwidth", module=_A + "handle.zwidth", plot=_A + "handle.plots:zwidth_plots",
                       fidelity="grid points per axis: draft 10, standard 20, fine 40",
                       metrics=(
            _m("zwidth_wall_damping_Ns_per_m", "wall dampings B_e of the Z-width grid"),
            _m("zwidth_boundary_N_per_mm", "largest stable wall stiffness K_e at each B_e (null: none stable)"),
            _m("zwidth_peak_stiffness_N_per_mm", "highest point of that boundary"),
            _m("zwidth_peak_damping_Ns_per_m", "B_e at the peak"),
            _m("zwidth_max_stable_damping_Ns_per_m", "largest B_e with a stable K_e"),
            _m("zwidth_stable_fraction", "stable share of the (B_e, K_e) grid cells (0 … 1)"),
        )),
    ),
}


#: device -> "module:function" (design) -> '' when the design can be built, else why not (the message of
#: :attr:`Status.NOT_ASSEMBLABLE`). The one rule for designs that do not exist: :func:`evaluate_all` then
#: runs none of the device's evaluators and reports each as ``not-assemblable`` with every metric NaN
#: (:class:`NotBuilt`), so no evaluator reports ``ok`` (or any number) for a device that cannot be put
#: together. The 3-PRRR: the chain closes and the CAD lays the parts out
#: (:func:`hapticopt.analysis.prrr.geometry.assembly.check_built`).
ASSEMBLY: dict[str, str] = {"prrr": _A + "prrr.geometry.assembly:check_built"}


@dataclass(frozen=True, kw_only=True)
class NotBuilt:
    """The result of every evaluator of a design that cannot be built (:data:`ASSEMBLY`): the entry's
    metrics at the fidelity, each NaN (JSON null), status ``not-assemblable`` with the reason."""

    names: tuple[str, ...]
    message: str
    status: Status = Status.NOT_ASSEMBLABLE

    def metrics(self) -> dict[str, float]:
        return dict.fromkeys(self.names, float("nan"))

    @classmethod
    def of(cls, entry: EvaluatorEntry, fidelity: Fidelity, message: str) -> NotBuilt:
        return cls(names=tuple(m.name for m in entry.metrics if Fidelity(fidelity) in m.fidelities), message=message)


def not_built(design: Any) -> str:
    """'' when ``design`` can be built (:data:`ASSEMBLY`; a device without a rule always can), else why not."""
    rule = ASSEMBLY.get(design.device)
    return _function(rule)(design) if rule is not None else ""


#: device -> "module:class" of the steps several of its evaluators take for one design: one object per
#: :func:`evaluate_all` call, made for that call's design and passed as ``shared=`` to the entries with
#: ``shared=True``, so that each step runs once per call (none for a device not named here)
SHARED_STEPS: dict[str, str] = {"prrr": _A + "prrr.shared:DesignSteps"}


@dataclass(frozen=True, kw_only=True)
class BatchEntry:
    """A device's batch evaluator: :func:`evaluate_all` of many designs at one fidelity in one pass."""

    fidelity: Fidelity  # the one level it serves (the others: one design at a time)
    evaluate_many: str  # "module:function" (designs, *, only, compute) -> per design (name -> result or the
    # exception raised, name -> seconds), every evaluator of the device in ``only``
    single_path: str  # "module:function" (designs, *, compute) -> per design '' (batched) or why it takes the
    # single path instead (a design that cannot be built, :data:`ASSEMBLY`: :class:`NotBuilt` for every evaluator)
    chunk: int  # designs per pass at most (the single-path check's verdicts stay cached for the evaluators)


#: device -> its batch evaluator (none for a device not named here)
BATCHED: dict[str, BatchEntry] = {
    "prrr": BatchEntry(fidelity=Fidelity.DRAFT, evaluate_many=_A + "prrr.draft_batch:evaluate_many",
                       single_path=_A + "prrr.geometry.assembly:check_built_many", chunk=1024),
}


def _function(spec: str) -> Callable[..., Any]:
    module, _, name = spec.partition(":")
    return getattr(importlib.import_module(module), name)


#: unit tokens a metric name may end with (``_N``, ``_N_per_mm``, ``_MPa_per_N`` …) -> printed symbol
UNIT_SYMBOLS: dict[str, str] = {
    "mm": "mm", "m": "m", "um": "µm", "mm3": "mm³", "deg": "deg", "rad": "rad", "kg": "kg", "g": "g",
    "N": "N", "Nm": "N·m", "Ns": "N·s", "Nms": "N·m·s", "Hz": "Hz", "s": "s", "ms": "ms", "MPa": "MPa",
    "GPa": "GPa", "pct": "%",
}


def metric_unit(name: str) -> str:
    """The unit a metric's name ends with, as printed (``stiffness_limit_N_per_mm`` → ``N/mm``,
    ``growth_rate_per_s`` → ``1/s``,
    ``*_deg`` → ``deg``, ``*_pct`` → ``%``); '' for a dimensionless metric. ``name[i]`` allowed."""
    parts = name.split("[")[0].split("_")
    if len(parts) >= 3 and parts[-2] == "per" and parts[-1] in UNIT_SYMBOLS:
        top = UNIT_SYMBOLS.get(parts[-3], "1")  # growth_rate_per_s: 1/s
        return f"{top}/{UNIT_SYMBOLS[parts[-1]]}"
    if len(parts) >= 2 and parts[-1] in UNIT_SYMBOLS:
        return UNIT_SYMBOLS[parts[-1]]
    return ""


class Direction(StrEnum):
    """Which way a metric is better: ``compare`` and the reports colour a change by it."""

    HIGHER = "higher"  # a larger value is better (stiffness, workspace, bandwidth, force)
    LOWER = "lower"  # a smaller value is better (mass, condition number, stress, size)
    NEUTRAL = "neutral"  # neither: a location, a design input, a range, a count, a time


_H, _L, _0 = Direction.HIGHER, Direction.LOWER, Direction.NEUTRAL

#: metric name (every device: a name means one thing) -> which way it is better; the one table.
#: A metric registered in :data:`EVALUATORS` without a line here fails tests/analysis/test_registry.py
#: (add it here); at run time an unknown name (a verification metric, a record from an older version)
#: is neutral. A vector metric has one direction for all its components.
DIRECTIONS: dict[str, Direction] = {
    # 3-PRRR statics
    "jacobian_condition": _L, "jacobian_condition_frobenius": _L, "max_force_N": _H, "max_pure_force_N": _H,
    "stiffness_limit_N_per_mm": _H, "effective_mass_kg": _L,
    # 3-PRRR structure
    "structural_stiffness_N_per_mm": _H, "elastic_centre_mm": _0, "structural_stiffness_at_elastic_centre_N_per_mm": _H,
    "structural_load_height_mm": _0, "structural_condition": _L, "structural_stiffness_fea_bonded_N_per_mm": _H,
    "structural_stiffness_frame_bonded_N_per_mm": _H, "structural_fea_dofs": _0, "structural_fea_wall_s": _0,
    "structural_fea_max_von_mises_MPa_per_N": _L, "structural_fea_max_von_mises_at_mm": _0,
    # 3-PRRR workspace, interference, free workspace
    "workspace_volume_mm3": _H, "workspace_cylinder_diameter_mm": _H, "workspace_cylinder_height_mm": _H,
    "workspace_height_at_diameter_mm": _H, "workspace_required_diameter_mm": _0, "footprint_diameter_mm": _L,
    "link_sweep_diameter_mm": _L, "workspace_footprint_ratio": _H, "jacobian_condition_deviation": _L,
    "workspace_interference_removed_fraction": _L, "workspace_free_volume_mm3": _H,
    "interference_removed_fraction": _L, "interference_overlap_fraction": _L,
    "workspace_free_radius_mm": _H, "workspace_free_cylinder_diameter_mm": _H, "workspace_free_cylinder_height_mm": _H,
    "workspace_free_height_at_diameter_mm": _H, "workspace_free_footprint_ratio": _H,
    # 3-PRRR size, joints, loop
    "device_mass_kg": _L, "device_mass_sea_modules_kg": _L, "device_mass_links_kg": _L, "device_mass_frame_kg": _L,
    "device_height_mm": _L, "joint_elbow_limit_deg": _H, "joint_limit_margin_deg": _H, "joint_range_r1_deg": _0,
    "joint_range_r2_deg": _0, "joint_range_r3_deg": _0, "force_loop_bandwidth_Hz": _H,
    "closed_loop_stiffness_limit_N_per_mm": _H,
    # master workspace, balance, transparency
    "workspace_coverage": _H, "workspace_required_box_mm": _0, "workspace_centroid_mm": _0, "workspace_box_centre_mm": _0,
    "global_conditioning_index": _H, "jacobian_condition_min": _L, "jacobian_condition_max": _L,
    "max_unbalance_force_N": _L, "unbalance_radius_mm": _H, "com_offset_mm": _0, "com_inside_unbalance_radius": _H,
    "unbalance_ellipse_axes_mm": _H, "unbalance_ellipse_overlap_pct": _0, "unbalance_ellipse_fit_mm": _0,
    "unbalance_ellipse_tilt_deg": _0, "balancing_counterweights_kg": _L, "moving_mass_kg": _L,
    "transparency_bandwidth_Hz": _H, "transparency_bandwidth_min_Hz": _H, "apparent_mass_kg": _L,
    "transparency_bandwidth_worst_Hz": _H,
    # handle stability, upsampling, Z-width (model cross-checks and sweep axes are neutral)
    "max_stable_stiffness_N_per_mm": _H, "pade_stable_stiffness_N_per_mm": _0, "pade_minus_exact_pct": _0,
    "eq19_stable_stiffness_N_per_mm": _0, "wall_stable": _H, "wall_margin": _H, "eq22_operator_stiffness_N_per_mm": _0,
    "critical_operator_stiffness_N_per_mm": _H, "max_stable_stiffness_vs_period_N_per_mm": _H, "sweep_period_ms": _0,
    "max_stable_stiffness_vs_wall_damping_N_per_mm": _H, "sweep_wall_damping_Ns_per_m": _0,
    "max_stable_stiffness_vs_operator_stiffness_N_per_mm": _H, "sweep_operator_stiffness_N_per_mm": _0,
    "upsampling": _0, "max_stable_stiffness_none_N_per_mm": _H, "max_stable_stiffness_as_printed_N_per_mm": _H,
    "upsampling_as_printed_vs_none_pct": _H, "max_stable_stiffness_as_intended_N_per_mm": _H,
    "upsampling_as_intended_vs_none_pct": _H, "upsampling_default_variant": _0,
    "zwidth_wall_damping_Ns_per_m": _0, "zwidth_boundary_N_per_mm": _H, "zwidth_peak_stiffness_N_per_mm": _H,
    "zwidth_peak_damping_Ns_per_m": _0, "zwidth_max_stable_damping_Ns_per_m": _H, "zwidth_stable_fraction": _H,
    # size and strength (issues 30 and 32; the part, load, pose and material named are neutral)
    "device_diameter_mm": _L, "workspace_free_device_ratio": _H, "safety_factor_yield": _H,
    "safety_factor_fatigue": _H, "safety_factor_yield_per_part": _H, "strength_max_von_mises_MPa": _L,
    "strength_fea_max_von_mises_MPa_per_N_per_part": _L, "strength_frame_max_von_mises_MPa_per_N_per_part": _L,
    "strength_frame_vs_fea_pct": _0, "strength_fea_governing_part": _0, "strength_governing_part": _0,
    "strength_governing_load": _0, "strength_governing_pose_mm": _0, "strength_material": _0,
    "strength_poses_unreachable": _0, "strength_rated_force_N": _0,
}

#: a change smaller than this, relative to the larger magnitude of the two values, is no change (rounding:
#: another BLAS kernel, a reordered sum); ``compare`` and the reports state it
SAME_REL_TOL = 1e-6


def metric_direction(name: str) -> Direction:
    """Which way ``name`` (``name[i]`` allowed) is better; neutral for a name not in :data:`DIRECTIONS`."""
    return DIRECTIONS.get(name.split("[")[0], Direction.NEUTRAL)


def judge(name: str, reference: float, value: float, *, rel_tol: float = SAME_REL_TOL) -> str:
    """``value`` against ``reference`` for metric ``name``: ``better``, ``worse``, ``changed`` (a neutral
    metric moved), ``same`` (within ``rel_tol`` of the larger magnitude) or ``''`` (either not a finite number)."""
    try:
        a, b = float(reference), float(value)
    except (TypeError, ValueError):
        return ""
    if not (np.isfinite(a) and np.isfinite(b)):
        return ""
    if abs(b - a) <= rel_tol * max(abs(a), abs(b)):
        return "same"
    direction = metric_direction(name)
    if direction is Direction.NEUTRAL:
        return "changed"
    return "better" if (b > a) == (direction is Direction.HIGHER) else "worse"


def glossary(device: str | None = None) -> list[dict[str, Any]]:
    """Every metric of one device (or all), in report order: device, evaluator, module, name, unit,
    description, fidelity levels and what the levels change. The source of ``hapticopt metrics``
    and docs/metrics.md."""
    if device is not None and device not in EVALUATORS:
        raise InvalidInput(f"--device = {device!r} is not a device: allowed {', '.join(EVALUATORS)}")
    rows = []
    for dev in ([device] if device is not None else list(EVALUATORS)):
        for e in EVALUATORS[dev]:
            for m in e.metrics:
                rows.append({"device": dev, "evaluator": e.name, "module": e.module, "metric": m.name,
                             "unit": m.unit, "description": m.description,
                             "fidelities": [str(f) for f in m.fidelities], "fidelity_note": e.fidelity})
    return rows


def jsonable(value: Any) -> Any:
    """A metric value as plain JSON types (numpy scalars and arrays become floats and lists)."""
    if isinstance(value, (bool, str)) or value is None:
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    return str(value)


def describe_failure(exc: BaseException) -> str:
    """``Type: message (file.py:line)`` of the innermost frame that raised."""
    frames = traceback.extract_tb(exc.__traceback__) if exc.__traceback__ else []
    where = f" ({frames[-1].filename.rsplit('/', 1)[-1]}:{frames[-1].lineno})" if frames else ""
    return f"{type(exc).__name__}: {exc}{where}"


@dataclass(frozen=True, kw_only=True)
class Evaluation:
    """Results of every evaluator for one design at one fidelity."""

    fidelity: Fidelity
    results: dict[str, Any]  # evaluator name -> frozen result (evaluators that did not raise)
    timings_s: dict[str, float]
    statuses: dict[str, Status] = field(default_factory=dict)
    messages: dict[str, str] = field(default_factory=dict)
    sources: dict[str, str] = field(default_factory=dict)  # metric name -> evaluator module

    def metrics(self) -> dict[str, Any]:
        """Every metric of every evaluator, as plain JSON values."""
        out: dict[str, Any] = {}
        for result in self.results.values():
            out.update(jsonable(result.metrics()))
        return out

    def failures(self) -> str:
        """``name: message`` of every failed evaluator, joined by '; ' ('' when none failed)."""
        return "; ".join(f"{name}: {self.messages.get(name) or 'failed'}"
                         for name, st in self.statuses.items() if st is Status.FAILED)


#: ``progress(evaluator, done, total)``: called before each evaluator runs and once at the end ('', n, n)
StepFn = Callable[[str, int, int], None]


def _collect(fidelity: Fidelity, entries: list[EvaluatorEntry], produce: Callable[[EvaluatorEntry], Any],
             timing: Callable[[EvaluatorEntry, float], float], progress: StepFn | None = None) -> Evaluation:
    """The one failure policy: ``produce(entry)`` gives the evaluator's result (or raises, or returns
    the exception it raised); a failure is a ``failed`` status with its message, not a crash.
    ``timing(entry, measured_s)`` gives the seconds recorded for it."""
    ev = Evaluation(fidelity=fidelity, results={}, timings_s={})
    for k, entry in enumerate(entries):
        if progress is not None:
            progress(entry.name, k, len(entries))
        t0 = time.perf_counter()
        try:
            result = produce(entry)
        except Exception as exc:  # noqa: BLE001 - recorded as a failure by _record
            result = exc
        _record(ev, entry, result)
        ev.timings_s[entry.name] = timing(entry, time.perf_counter() - t0)
    if progress is not None:
        progress("", len(entries), len(entries))
    return ev


def _collect_found(fidelity: Fidelity, entries: list[EvaluatorEntry], found: Mapping[str, Any],
                   times: Mapping[str, float]) -> Evaluation:
    """:func:`_collect` of results computed beforehand (the batch's: evaluator name → result or the
    exception raised, and the seconds recorded for it, 0 where absent), without a timer per entry."""
    ev = Evaluation(fidelity=fidelity, results={}, timings_s={})
    for entry in entries:
        try:
            result = found[entry.name]
        except Exception as exc:  # noqa: BLE001 - recorded as a failure by _record
            result = exc
        _record(ev, entry, result)
        ev.timings_s[entry.name] = times.get(entry.name, 0.0)
    return ev


def _record(ev: Evaluation, entry: EvaluatorEntry, result: Any) -> None:
    """Put one evaluator's ``result`` (or the exception it raised) into ``ev``: the failure policy."""
    try:
        if isinstance(result, BaseException):
            raise result
        names = result.metrics()
    except Exception as exc:  # noqa: BLE001 - the one failure policy: a status, not a crash
        ev.statuses[entry.name] = Status.FAILED
        ev.messages[entry.name] = describe_failure(exc)
    else:
        ev.results[entry.name] = result
        status = result.status
        ev.statuses[entry.name] = status if type(status) is Status else Status(status)
        ev.messages[entry.name] = result.message
        ev.sources.update(dict.fromkeys(names, entry.module))


def _entries(device: str, only: tuple[str, ...] | None, fidelity: Fidelity) -> list[EvaluatorEntry]:
    """The evaluators a call runs: those named in ``only``, else every one of the device except those
    that run at this fidelity only on request (:attr:`EvaluatorEntry.on_request_at`)."""
    if only is not None:
        return [e for e in EVALUATORS[device] if e.name in only]
    return [e for e in EVALUATORS[device] if str(Fidelity(fidelity)) not in e.on_request_at]


def evaluate_all(design: Any, *, fidelity: Fidelity = Fidelity.STANDARD,
                 only: tuple[str, ...] | None = None, progress: StepFn | None = None,
                 compute: Compute = DEFAULT) -> Evaluation:
    """Run every evaluator registered for the design's device (or those named in ``only``); the steps
    several of them take for the design (:data:`SHARED_STEPS`) run once for the call; ``compute`` goes to
    the evaluators whose entry says ``takes_compute``. A design that cannot be built (:data:`ASSEMBLY`)
    runs none: every evaluator is :class:`NotBuilt` (``not-assemblable``, its metrics NaN)."""
    entries = _entries(design.device, only, fidelity)
    why = not_built(design)
    if why:
        return _collect(fidelity, entries, lambda entry: NotBuilt.of(entry, fidelity, why),
                        lambda entry, measured: measured, progress)
    shared = None
    if design.device in SHARED_STEPS and any(e.shared for e in entries):
        shared = _function(SHARED_STEPS[design.device])(design)

    def produce(entry: EvaluatorEntry) -> Any:
        kw: dict[str, Any] = {}
        if entry.shared and shared is not None:
            kw["shared"] = shared
        if entry.takes_compute:
            kw["compute"] = compute
        return entry.load().evaluate(design, fidelity=fidelity, **kw)

    return _collect(fidelity, entries, produce, lambda entry, measured: measured, progress)


def run_plotter(entry: EvaluatorEntry, design: Any, result: Any, out_dir: Path) -> list[Path]:
    """The pictures of one evaluator's ``result`` in ``out_dir`` (the files written).

    Plotters name their files ``<design name>_<what>.png`` in ``out_dir``: the name is checked
    (:func:`design.paths.check_name`) before, and every returned path is checked to lie inside
    ``out_dir``. A plotter returns its paths as written (``out_dir / name``: relative to the working
    folder when ``out_dir`` is), so they are checked as absolute paths and returned as written.
    """
    check_name(design.name, "design name", error=InvalidDesign)
    out_dir = Path(out_dir)
    plotter = entry.plotter()
    if plotter is None or isinstance(result, NotBuilt):  # nothing to draw of a device that cannot be built
        return []
    offscreen.configure()  # the plotters draw with pyvista: no X probe, no VTK warning
    written = [Path(p) for p in plotter(design, result, out_dir)]
    for p in written:
        inside(out_dir, p.absolute())  # not inside(out_dir, p): that reads a relative p as relative to out_dir
    return written


def write_plots(design: Any, evaluation: Evaluation, out_dir: Path) -> list[Path]:
    """Every registered picture of the evaluators that produced a result; the files written."""
    check_name(design.name, "design name", error=InvalidDesign)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for entry in EVALUATORS[design.device]:
        if entry.name in evaluation.results:
            written.extend(run_plotter(entry, design, evaluation.results[entry.name], out_dir))
    return written


def evaluate_batch(designs: list[Any], *, fidelity: Fidelity = Fidelity.STANDARD,
                   only: tuple[str, ...] | None = None, compute: Compute = DEFAULT) -> list[Evaluation]:
    """:func:`evaluate_all` of many designs: equal results and statuses, and the same failure policy.
    Designs of one device with a batch evaluator (:data:`BATCHED`) at its fidelity go through it, chunk by
    chunk, except those its ``single_path`` check sends to :func:`evaluate_all`; any other list is
    evaluated one design at a time."""
    designs = list(designs)
    devices = {d.device for d in designs}
    batch = BATCHED.get(devices.pop()) if len(devices) == 1 else None
    if batch is None or Fidelity(fidelity) is not batch.fidelity:
        return [evaluate_all(d, fidelity=fidelity, only=only, compute=compute) for d in designs]
    single_path, evaluate_many = _function(batch.single_path), _function(batch.evaluate_many)
    entries = _entries(designs[0].device, only, fidelity)
    only = tuple(e.name for e in entries)  # the batch runs exactly these (no on-request evaluator unasked)
    out: list[Evaluation] = []
    for c in range(0, len(designs), batch.chunk):
        chunk = designs[c:c + batch.chunk]
        single = {i for i, why in enumerate(single_path(chunk, compute=compute)) if why}
        found_all = iter(evaluate_many([d for i, d in enumerate(chunk) if i not in single], only=only,
                                       compute=compute))
        for i, design in enumerate(chunk):
            if i in single:
                out.append(evaluate_all(design, fidelity=fidelity, only=only, compute=compute))
            else:
                found, times = next(found_all)
                out.append(_collect_found(batch.fidelity, entries, found, times))
    return out
