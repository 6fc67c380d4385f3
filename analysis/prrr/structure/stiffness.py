"""Structural stiffness of the 3-PRRR: frame model in the loop, solid FEA to verify.

Metrics (seed 002 section 2.3, Table 3): the Cartesian stiffness [x, y, z] for a force applied
Δz = 58 mm above the end-effector (sliders locked), the elastic centre (height above the
end-effector on the z axis where a lateral force and the rotation decouple) and the stiffness
when loaded there. ``draft``/``standard`` fidelity: the Timoshenko frame model
(:mod:`hapticopt.analysis.prrr.structure.frame_model`: pins as bonded necks, numpy path, ~3–5 ms, no compilation).
``fine``: additionally the solid FEA of the CAD geometry with bonded pins (:mod:`hapticopt.analysis.prrr.structure.fea_cad`, level 2, ~20–40 s),
reported next to the frame model with bonded joints at the CAD's elbow branch, the model it checks.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from hapticopt.analysis.prrr.structure import frame_model as fm
from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.design.errors import InvalidDesign, InvalidInput
from hapticopt.design.prrr.params import PrrrDesign
from hapticopt.analysis.fem.stress import element_stress
from hapticopt.analysis.prrr.geometry import assembly
from hapticopt.analysis.prrr.structure import fea_cad
from hapticopt.design.prrr.cad import DEFAULT_BRANCH


@dataclass(frozen=True, kw_only=True)
class StructuralStiffness:
    """Structural stiffness of one design at one pose [SI]."""

    pose: np.ndarray  # end-effector position (3,) [m]
    load_height: float  # Δz of the load point above the end-effector [m]
    stiffness_load: np.ndarray  # (3,) [N/m] k_i = 1/C_ii at the load point
    elastic_centre: float  # height of the elastic centre above the end-effector [m]
    stiffness_elastic_centre: np.ndarray  # (3,) [N/m]
    compliance_ee: np.ndarray  # (6, 6) compliance at the end-effector [SI]
    coupling_residual: float  # see hapticopt.analysis.prrr.structure.frame_model.frame_arrays
    condition: float  # condition estimate of the stiffness matrix
    options: fm.FrameOptions
    fea: Any = None  # hapticopt.analysis.prrr.structure.fea_cad.CadFeaResult at fine fidelity
    stiffness_load_frame_bonded: np.ndarray | None = None  # (3,) [N/m] frame with bonded joints (FEA's model)
    fea_stress: Any = None  # hapticopt.analysis.fem.stress.ElementStress of the FEA's 1 N x load case (fine)
    status: Status = Status.OK
    message: str = ""

    def metrics(self) -> dict[str, object]:
        """Engineering-unit metrics (names carry their units); NaN (the condition excepted) unless ok."""
        if self.status is not Status.OK:
            nan = float("nan")
            return {"structural_stiffness_N_per_mm": [nan] * 3, "elastic_centre_mm": nan,
                    "structural_stiffness_at_elastic_centre_N_per_mm": [nan] * 3,
                    "structural_load_height_mm": float(self.load_height) * 1e3,
                    "structural_condition": float(self.condition)}
        out: dict[str, object] = {
            "structural_stiffness_N_per_mm": [x * 1e-3 for x in np.asarray(self.stiffness_load, dtype=float).tolist()],
            "elastic_centre_mm": float(self.elastic_centre) * 1e3,
            "structural_stiffness_at_elastic_centre_N_per_mm": [
                x * 1e-3 for x in np.asarray(self.stiffness_elastic_centre, dtype=float).tolist()],
            "structural_load_height_mm": float(self.load_height) * 1e3,
            "structural_condition": float(self.condition),
        }
        if self.fea is not None:
            out["structural_stiffness_fea_bonded_N_per_mm"] = [float(x) * 1e-3 for x in self.fea.stiffness_load]
            out["structural_stiffness_frame_bonded_N_per_mm"] = [float(x) * 1e-3
                                                                 for x in self.stiffness_load_frame_bonded]
            out["structural_fea_dofs"] = int(self.fea.n_dofs)
            out["structural_fea_wall_s"] = float(self.fea.wall_s)
        if self.fea_stress is not None:
            out["structural_fea_max_von_mises_MPa_per_N"] = float(self.fea_stress.max_von_mises) * 1e-6
            out["structural_fea_max_von_mises_at_mm"] = [float(x) * 1e3 for x in self.fea_stress.max_location]
        return out


def _status(out: dict[str, np.ndarray]) -> tuple[Status, str]:
    values = [out[k] for k in ("stiffness_load", "stiffness_elastic_centre", "elastic_centre", "compliance_ee")]
    cond = float(out["condition"])
    if not all(np.all(np.isfinite(v)) for v in values) or not np.isfinite(cond):
        return Status.SINGULAR, "frame stiffness matrix is singular (non-finite compliance)"
    if cond >= fm.SINGULAR_COND:
        return Status.SINGULAR, (f"frame stiffness matrix is numerically singular (condition ≈ {cond:.2g} ≥ "
                                 f"{fm.SINGULAR_COND:.0e}): results meaningless")
    if cond > fm.COND_LIMIT:
        return Status.ILL_CONDITIONED, (f"frame stiffness matrix is ill-conditioned (condition ≈ {cond:.2g} > "
                                 f"{fm.COND_LIMIT:.0e}): results unreliable")
    if np.any(np.diagonal(out["compliance_ee"]) <= 0.0):
        return Status.NOT_POSITIVE_DEFINITE, "frame stiffness matrix is not positive definite"
    return Status.OK, ""


def structural_stiffness(design: PrrrDesign, *, p=(0.0, 0.0, 0.0), load_height: float = fm.LOAD_HEIGHT,
                         options: fm.FrameOptions = fm.FrameOptions()) -> StructuralStiffness:
    """Frame-model stiffness of ``design`` at end-effector position ``p`` [m].

    Raises :class:`InvalidInput` if ``p`` is outside the reach or the slider stroke, or if
    ``load_height`` is not finite. An ill-conditioned or singular stiffness matrix is a value:
    status ``SINGULAR`` with the condition estimate in the message.
    """
    if not np.isfinite(load_height):
        raise InvalidInput(f"load_height = {load_height!r} m is not finite: allowed any finite height (m)")
    p = np.asarray(p, dtype=float)
    out = None
    if options == fm.FrameOptions() and not np.any(p):  # home: the legs the strength evaluator reads too
        try:
            out = fm.home_arrays(design, load_height)
        except np.linalg.LinAlgError:  # solve_frame's fallback (the jax path) decides
            out = None
    if out is None:
        # numpy parameters: solve_frame takes numpy arrays (jax scalars here cost an XLA transfer each, same values)
        out = fm.solve_frame(fm.frame_params_of(design, xp=np), p=p, load_height=load_height, options=options)
    return from_arrays(design, out, p=p, load_height=load_height, options=options)


def from_arrays(design: PrrrDesign, out: dict, *, p, load_height: float, options: fm.FrameOptions
                ) -> StructuralStiffness:
    """The result of ``design`` from its :func:`hapticopt.analysis.prrr.structure.frame_model.frame_arrays`
    (numpy, or a row of the batched draft evaluator's jax batch): the one place of the verdict.
    Raises :class:`InvalidInput` if the pose is outside the reach or the slider stroke."""
    p = np.asarray(p, dtype=float)
    if not bool(out["reachable"]):
        raise InvalidInput(
            f"pose p_mm = ({', '.join(f'{x * 1e3:g}' for x in p)}) is outside the reach or slider stroke of "
            f"design {design.name!r} (margin {float(out['reach_margin']) * 1e3:.3g} mm): allowed margin ≥ 0 mm")
    status, message = _status(out)
    return _result(out, p, load_height, options, status, message)


def ok_many(out: dict) -> np.ndarray:
    """(n,) bool: the rows of stacked :func:`hapticopt.analysis.prrr.structure.frame_model.frame_arrays` ``out``
    (leading axis: the batched draft evaluator's designs) whose pose is reached and whose
    :func:`from_arrays` verdict is ok, by :func:`_status`'s rule in one pass over every row: every
    value finite, condition below both limits, a positive compliance diagonal."""
    cond = np.asarray(out["condition"], dtype=float)
    n = len(cond)
    ok = np.asarray(out["reachable"], dtype=bool).reshape(n) & np.isfinite(cond)
    for k in ("stiffness_load", "stiffness_elastic_centre", "elastic_centre", "compliance_ee"):
        ok &= np.all(np.isfinite(np.reshape(out[k], (n, -1))), axis=1)
    with np.errstate(invalid="ignore"):
        ok &= (cond < fm.SINGULAR_COND) & (cond <= fm.COND_LIMIT)
        ok &= np.all(np.diagonal(out["compliance_ee"], axis1=-2, axis2=-1) > 0.0, axis=1)
    return ok


def from_ok_arrays(out: dict, *, p, load_height: float, options: fm.FrameOptions) -> StructuralStiffness:
    """The result of a row of ``out`` that :func:`ok_many` passed (status ok): :func:`from_arrays`
    without the checks it has made."""
    return _result(out, np.asarray(p, dtype=float), load_height, options, Status.OK, "")


def _result(out: dict, p: np.ndarray, load_height: float, options: fm.FrameOptions, status: Status,
            message: str) -> StructuralStiffness:
    return StructuralStiffness(
        pose=p, load_height=float(load_height), stiffness_load=out["stiffness_load"],
        elastic_centre=float(out["elastic_centre"]), stiffness_elastic_centre=out["stiffness_elastic_centre"],
        compliance_ee=out["compliance_ee"], coupling_residual=float(out["coupling_residual"]),
        condition=float(out["condition"]), options=options, status=status, message=message)


def evaluate(design: PrrrDesign, *, fidelity: Fidelity = Fidelity.STANDARD,
             compute: Compute = DEFAULT) -> StructuralStiffness:  # one route for one design (the registry passes it to every entry alike)
    """Structural stiffness at the home pose, load Δz = 58 mm (seed 002 Table 3).

    ``not-assemblable`` (metrics NaN) when the chain does not close
    (:func:`hapticopt.analysis.prrr.geometry.assembly.closure`); ``failed`` when it closes but not at the
    home pose (the load case is defined there).

    ``fine`` adds the solid FEA of the CAD with bonded pins (CAD elbow branch) and the
    bonded-joint frame model at that branch.
    """
    blocked = assembly.closure(design)
    try:
        if blocked:
            raise InvalidInput(blocked)
        result = structural_stiffness(design)
    except (InvalidInput, InvalidDesign) as exc:  # unreachable home pose; no carriage face can carry R1
        return failed(str(exc), Status.NOT_ASSEMBLABLE if blocked else Status.FAILED)
    return _finish(design, result, fidelity)


def failed(message: str, status: Status = Status.FAILED) -> StructuralStiffness:
    """The result where the home pose cannot be evaluated (NaN metrics): ``failed``, or
    ``not-assemblable`` when the chain does not close."""
    nan3 = np.full(3, np.nan)
    return StructuralStiffness(pose=np.zeros(3), load_height=fm.LOAD_HEIGHT, stiffness_load=nan3,
                               elastic_centre=float("nan"), stiffness_elastic_centre=nan3,
                               compliance_ee=np.full((6, 6), np.nan), coupling_residual=float("nan"),
                               condition=float("nan"), options=fm.FrameOptions(), status=status,
                               message=message)


def _finish(design: PrrrDesign, result: StructuralStiffness, fidelity: Fidelity) -> StructuralStiffness:
    if fidelity != Fidelity.FINE:
        return result

    bonded = structural_stiffness(design, options=fm.FrameOptions(joints=fm.Joints.BONDED, branch=DEFAULT_BRANCH))
    try:
        fea_result = fea_cad.fine_fea(design)  # level DEFAULT_LEVEL with fields; shared with the strength evaluator
    except Exception as exc:  # CAD/gmsh failures become a status, the frame metrics stay
        return replace(result, status=Status.FAILED, message=f"CAD FEA failed: {exc}")
    status, message = result.status, result.message
    if fea_result.status != Status.OK:
        status, message = fea_result.status, f"FEA: {fea_result.message}"
    return replace(result, fea=fea_result, stiffness_load_frame_bonded=bonded.stiffness_load,
                   fea_stress=fea_element_stress(design, fea_result), status=status, message=message)


def fea_element_stress(design: PrrrDesign, fea_result):
    """Element von Mises stress of the FEA's 1 N x load case (hapticopt.analysis.fem.stress), or None without the P2 field."""
    u_edges = getattr(fea_result, "displacement_edges", None)
    if fea_result.mesh is None or fea_result.displacement is None or u_edges is None:
        return None

    return element_stress(fea_result.mesh.points, fea_result.mesh.tets, fea_result.displacement, u_edges,
                          youngs_modulus=design.structure.youngs_modulus,
                          poisson_ratio=design.structure.poisson_ratio)
