"""Strength of the 3-PRRR: member stresses of the frame model, safety factors, the governing part and pose.

The frame model (:mod:`.frame_model`, the same legs, elements and pin-neck springs as the stiffness)
is solved at each pose of :func:`poses` for the load cases of :func:`load_cases`; every member's end
forces (:func:`.frame_beam.beam_end_forces`) give its section stresses, every pin neck's spring force
the pin's (docs/strength.md):

* link, bracket and platform-arm members (rectangle b × t, local y × z): normal stress
  σ = |N|/A + |M_y|·(t/2)/I_y + |M_z|·(b/2)/I_z at the section corner; shear
  τ = T (3a + 1.8c)/(a² c²) (Roark, Table 10.7 case 4, a ≥ c the sides) + 1.5 |V|/A; the von Mises
  combination √(σ² + 3τ²) of these maxima (they occur at different points of the section:
  conservative), at both ends of the flexible part (the internal moments are linear along a beam
  without loads between its nodes, so the ends hold the largest);
* pins (solid circle of the bore diameter d, the neck across the clearance gap g): the spring's force
  and moment split along the joint axis w, bending at the boss face M + V g/2, σ = |F_w|/A + 32 M/(πd³),
  τ = 16 |T_w|/(πd³) + 4|V|/(3A).

Load cases: the device's rated force (the statics' per-axis maximum, seed 002 Table 1: 1378, 1194,
3581 N for prrr-paper) along +x, −x, +y, −y, +z, −z at the load point Δz = 58 mm above the
end-effector (seed 002 Table 3's load height; the handle), each with the own weight of the moving
mass (the end-effector's equivalent mass M, which includes the links, seed 002 Table 4) at the
end-effector. Sliders locked (the SEA springs are in series with the actuators, not in the links).

Poses (:func:`poses`): ``draft`` the home pose only (the draft level's time budget: one frame solve);
``standard`` and ``fine`` the home pose, six on the rim of the φ140 mm workspace at mid-height
(towards and away from each leg: γ_i and γ_i + π) and the top and bottom of its 89 mm height on the
axis (seed 002 Table 1's workspace), nine in all; the worst (smallest safety factor) over poses and
load cases governs. Poses a design cannot reach are skipped (counted in the metrics).

Safety factors: yield strength / peak von Mises stress (the material of ``structure.material``,
:mod:`hapticopt.design.materials`); fatigue strength / stress amplitude, the rated force taken as
fully reversed, ``FATIGUE_CYCLES`` = 1e7 cycles assumed (a full-force reversal every 3.6 s of an 8-hour
day, 250 days a year for 5 years), compared with the material's S-N point (at 1e7 cycles, or the
library's stated count: 5e8 for aluminium, conservative at 1e7). No surface, size or notch factors.

``fine`` adds the solid FEA's check: the FEA (:mod:`.fea_cad`, bonded pins, home pose, 1 N along x at
the load point, the stiffness evaluator's case) gives each part's largest element von Mises stress; the
frame with bonded joints at the CAD's elbow branch gives the same case's, and the relative difference
for the part where the FEA's stress is largest is reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr.geometry import assembly
from hapticopt.analysis.prrr.structure import frame_model as fm
from hapticopt.analysis.prrr.structure.frame_beam import Section, SectionProperties, beam_end_forces
from hapticopt.analysis.status import Status
from hapticopt.design import materials
from hapticopt.design.errors import InvalidDesign, InvalidInput
from hapticopt.design.prrr.params import PrrrDesign

#: assumed full-force cycles over the device's life (see the module docstring)
FATIGUE_CYCLES = 1e7
#: standard gravity [m/s²]
GRAVITY = 9.80665
#: Table 1 workspace of seed 002: φ140 × 89 mm [m] (radius, half-height)
WORKSPACE_RADIUS, WORKSPACE_HALF_HEIGHT = 0.070, 0.0445
AXES = "xyz"


def poses(design: PrrrDesign, fidelity: Fidelity) -> np.ndarray:
    """(n, 3) [m] end-effector positions checked at ``fidelity`` (module docstring)."""
    home = np.zeros((1, 3))
    if Fidelity(fidelity) is Fidelity.DRAFT:
        return home
    gam = np.array([0.0, 2.0 * math.pi / 3.0, -2.0 * math.pi / 3.0])
    ang = np.concatenate([gam, gam + math.pi])
    rim = WORKSPACE_RADIUS * np.stack([np.cos(ang), np.sin(ang), np.zeros(6)], axis=1)
    ends = np.array([[0.0, 0.0, WORKSPACE_HALF_HEIGHT], [0.0, 0.0, -WORKSPACE_HALF_HEIGHT]])
    return np.concatenate([home, rim, ends])


def rated_force(design: PrrrDesign) -> np.ndarray:
    """(3,) [N] the largest end-effector force per axis the actuators can produce (the statics'
    ``max_force_N``: F_max Σ_j |J⁻ᵀ_ij|, seed 002 Table 1)."""
    from hapticopt.analysis.prrr.structure import statics

    st = statics.evaluate(design)
    return np.asarray(st.max_force, dtype=float)


def load_cases(design: PrrrDesign, force: np.ndarray, load_height: float) -> tuple[np.ndarray, list[str]]:
    """The wrenches at the end-effector (6, 6) [N, N·m] (columns: ±x, ±y, ±z rated force at the
    load point, each with the own weight at the end-effector) and their labels."""
    W, labels = np.zeros((6, 6)), []
    h = np.array([0.0, 0.0, load_height])
    weight = np.array([0.0, 0.0, -design.end_effector.mass * GRAVITY])
    for a in range(3):
        for s, sign in ((0, 1.0), (1, -1.0)):
            F = np.zeros(3)
            F[a] = sign * force[a]
            W[:3, 2 * a + s] = F + weight
            W[3:, 2 * a + s] = np.cross(h, F)
            labels.append(f"{'+' if sign > 0 else '-'}{AXES[a]} {force[a]:.0f} N + weight")
    return W, labels


def rect_von_mises(f: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Peak von Mises stress [Pa] of a b × t rectangle (b along local y, t along local z) under section
    forces ``f`` (..., 6, m) = [N, V_y, V_z, T, M_y, M_z] (module docstring)."""
    b, t = np.asarray(b)[..., None], np.asarray(t)[..., None]
    A, Iy, Iz = b * t, b * t**3 / 12.0, t * b**3 / 12.0
    N, Vy, Vz, T, My, Mz = (np.abs(f[..., k, :]) for k in range(6))
    sigma = N / A + My * (0.5 * t) / Iy + Mz * (0.5 * b) / Iz
    a, c = np.maximum(b, t), np.minimum(b, t)
    tau = T * (3.0 * a + 1.8 * c) / (a**2 * c**2) + 1.5 * np.hypot(Vy, Vz) / A
    return np.sqrt(sigma**2 + 3.0 * tau**2)


def pin_von_mises(f: np.ndarray, w: np.ndarray, d: float, gap: float) -> np.ndarray:
    """Peak von Mises stress [Pa] of solid pins of diameter ``d`` across a gap ``gap`` [m] carrying the
    joint forces ``f`` (..., 6, m) [N; N·m] in global axes, axes ``w`` (..., 3) (module docstring)."""
    F, M = f[..., :3, :], f[..., 3:, :]
    w = np.asarray(w)[..., :, None]
    Fa, Ta = np.sum(w * F, axis=-2), np.sum(w * M, axis=-2)
    V = np.linalg.norm(F - w * Fa[..., None, :], axis=-2)
    Mb = np.linalg.norm(M - w * Ta[..., None, :], axis=-2) + 0.5 * gap * V
    A, Z = math.pi * d**2 / 4.0, math.pi * d**3 / 32.0
    sigma = np.abs(Fa) / A + Mb / Z
    tau = 16.0 * np.abs(Ta) / (math.pi * d**3) + 4.0 * V / (3.0 * A)
    return np.sqrt(sigma**2 + 3.0 * tau**2)


#: part of each member of a leg (``FrameOptions(pins=True)``, offsets as beams: the leg's elements in
#: :func:`.frame_model._leg_stiffness_pins` order) and of each pin-neck spring (the first two springs are
#: the carriage bracket's bonds, inside the carriage: their member stresses are the bracket's beams')
_MEMBERS = ("carriage_{i}", "carriage_{i}", "platform", "link1_{i}", "link2_{i}")
_PINS = (None, None, "pin_r1_{i}", "pin_r2_{i}", "pin_r3_{i}")


def part_stresses(fp, p, wrenches: np.ndarray, options: fm.FrameOptions = fm.FrameOptions(), parts=None
                  ) -> tuple[dict[str, np.ndarray], bool]:
    """Peak von Mises stress [Pa] of every part for each wrench at the end-effector (6, m) at pose
    ``p`` (3,) [m]: part name → (m,), and whether ``p`` is reachable (an empty dict when not). Numpy
    path of the frame model (``fp`` its numpy parameters; ``parts``: its :func:`.frame_model.frame_parts` at ``p``
    when the caller has them)."""
    if not (options.pins and options.offsets == fm.Offsets.BEAM and options.pin_model == fm.PinModel.NECK):
        raise ValueError("strength: the frame options must be the default layered-pin model (pins, beam "
                         "offsets, neck springs)")
    legs, contrib, _, recovery, ik = fm.frame_parts(fp, p, options) if parts is None else parts
    if not bool(ik.reachable):
        return {}, False
    if any(len(g[1]) != len(_MEMBERS) or len(g[2]) != len(_PINS) for g in legs):
        raise AssertionError("frame topology differs from the strength model's part list")  # a programming error
    KP = 0.5 * (np.sum(contrib, axis=0) + np.sum(contrib, axis=0).T)
    uP = np.linalg.solve(KP, wrenches)  # (6, m)
    m = wrenches.shape[1]
    q = np.concatenate([np.broadcast_to(uP, (3, 6, m)), -recovery @ uP], axis=1)  # (3 legs, n, m) every DOF
    # the three legs' members and pins in one call each (leg-major order)
    elems = [e for g in legs for e in g[1]]
    G = np.stack([np.concatenate([e[0], e[1]]) for e in elems])  # (3E, 12, n)
    X1, X2, Z, A1, A2 = (np.stack([np.asarray(e[j], dtype=float) for e in elems]) for j in (2, 3, 4, 5, 6))
    P = SectionProperties(*(np.stack([np.asarray(e[7][f], dtype=float) for e in elems]) for f in range(6)))
    E = len(_MEMBERS)
    d = G @ np.repeat(q, E, axis=0)  # (3E, 12, m)
    f = beam_end_forces(X1, X2, Z, Section(None, None, fp.section.youngs_modulus, None), A1, A2, d, np, props=P)
    b, t = np.sqrt(12.0 * P.i_z / P.area), np.sqrt(12.0 * P.i_y / P.area)
    vm = np.maximum(rect_von_mises(f[:, :6], b, t), rect_von_mises(f[:, 6:], b, t))  # (3E, m)
    pins = [(k, s, g[2][s]) for k, g in enumerate(legs) for s in range(len(_PINS)) if _PINS[s] is not None]
    fj = np.stack([Ks @ (D @ q[k]) for k, _, (D, Ks) in pins])  # (3 pins per leg, 6, m)
    wj = np.stack([legs[k][0] for k, _, _ in pins])
    vj = pin_von_mises(fj, wj, float(fp.pin_diameter), float(fp.layer - fp.section.thickness))
    out: dict[str, np.ndarray] = {}
    for r, name in enumerate(_MEMBERS * 3):
        name = name.format(i=r // E + 1)
        out[name] = vm[r] if name not in out else np.maximum(out[name], vm[r])
    for r, (k, s, _) in enumerate(pins):
        out[_PINS[s].format(i=k + 1)] = vj[r]
    return out, True


@dataclass(frozen=True, kw_only=True)
class Strength:
    """Safety factors of one design over its poses and load cases [SI]."""

    material: str
    rated_force: np.ndarray  # (3,) [N]
    part_stress: dict[str, float]  # [Pa] each part's peak von Mises over poses and load cases
    part_pose: dict[str, np.ndarray]  # [m] the pose of that peak
    part_load: dict[str, str]  # the load case of that peak
    yield_strength: float  # [Pa]
    fatigue_strength: float  # [Pa]
    fatigue_cycles: float  # the library's S-N point's cycle count
    n_poses: int
    n_unreachable: int
    fea_part_stress: dict[str, float] | None = None  # [Pa/N] fine: FEA, home, 1 N x at the load point
    frame_part_stress_fea_case: dict[str, float] | None = None  # [Pa/N] the frame (bonded) for that case
    status: Status = Status.OK
    message: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def governing(self) -> str:
        return max(self.part_stress, key=self.part_stress.get) if self.part_stress else ""

    def metrics(self) -> dict[str, object]:
        nan = float("nan")
        if self.status is not Status.OK or not self.part_stress:
            return {"safety_factor_yield": nan, "safety_factor_fatigue": nan, "strength_max_von_mises_MPa": nan,
                    "strength_governing_part": "", "strength_governing_pose_mm": [nan] * 3,
                    "strength_governing_load": "", "strength_rated_force_N": [float(x) for x in self.rated_force],
                    "strength_material": self.material, "safety_factor_yield_per_part": {},
                    "strength_poses_unreachable": int(self.n_unreachable)}
        g = self.governing
        peak = self.part_stress[g]
        out: dict[str, object] = {
            "safety_factor_yield": self.yield_strength / peak,
            "safety_factor_fatigue": self.fatigue_strength / peak,
            "strength_max_von_mises_MPa": peak * 1e-6,
            "strength_governing_part": g,
            "strength_governing_pose_mm": [float(x) * 1e3 for x in self.part_pose[g]],
            "strength_governing_load": self.part_load[g],
            "strength_rated_force_N": [float(x) for x in self.rated_force],
            "strength_material": self.material,
            "safety_factor_yield_per_part": {k: self.yield_strength / v for k, v in sorted(self.part_stress.items())},
            "strength_poses_unreachable": int(self.n_unreachable),
        }
        if self.fea_part_stress:
            fea, frame = self.fea_part_stress, self.frame_part_stress_fea_case
            top = max(fea, key=fea.get)
            out["strength_fea_max_von_mises_MPa_per_N_per_part"] = {k: v * 1e-6 for k, v in sorted(fea.items())}
            out["strength_frame_max_von_mises_MPa_per_N_per_part"] = {k: v * 1e-6 for k, v in sorted(frame.items())}
            out["strength_fea_governing_part"] = top
            out["strength_frame_vs_fea_pct"] = 100.0 * (frame.get(top, nan) / fea[top] - 1.0)
        return out


def evaluate(design: PrrrDesign, *, fidelity: Fidelity = Fidelity.STANDARD,
             compute: Compute = DEFAULT) -> Strength:  # one route for one design (the registry passes it to every entry alike)
    """Safety factors of ``design`` at ``fidelity`` (module docstring). ``not-assemblable`` when the
    chain does not close; ``failed`` when no pose of the set is reachable."""
    mat = materials.material(design.structure.material)
    blocked = assembly.closure(design)
    force = rated_force(design)
    base = dict(material=mat.name, rated_force=force, yield_strength=mat.yield_strength,
                fatigue_strength=mat.fatigue_strength, fatigue_cycles=mat.fatigue_cycles)
    if blocked:
        return Strength(**base, part_stress={}, part_pose={}, part_load={}, n_poses=0, n_unreachable=0,
                        status=Status.NOT_ASSEMBLABLE, message=blocked)
    W, labels = load_cases(design, force, fm.LOAD_HEIGHT)
    stress: dict[str, float] = {}
    where: dict[str, np.ndarray] = {}
    load: dict[str, str] = {}
    P = poses(design, fidelity)
    skipped = 0
    try:
        fp, home = fm.home_frame(design)
        for p in P:
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                parts, ok = part_stresses(fp, p, W, parts=home if not np.any(p) else None)
            if not ok:
                skipped += 1
                continue
            for name, s in parts.items():
                j = int(np.argmax(s))
                if not np.isfinite(s[j]):
                    raise np.linalg.LinAlgError("non-finite member stress")
                if s[j] > stress.get(name, -1.0):
                    stress[name], where[name], load[name] = float(s[j]), p, labels[j]
    except (np.linalg.LinAlgError, InvalidDesign, InvalidInput) as exc:
        return Strength(**base, part_stress={}, part_pose={}, part_load={}, n_poses=len(P), n_unreachable=skipped,
                        status=Status.FAILED, message=f"frame stress: {exc}")
    if not stress:
        return Strength(**base, part_stress={}, part_pose={}, part_load={}, n_poses=len(P), n_unreachable=skipped,
                        status=Status.FAILED, message="no pose of the strength check is reachable")
    result = Strength(**base, part_stress=stress, part_pose=where, part_load=load, n_poses=len(P),
                      n_unreachable=skipped)
    if Fidelity(fidelity) is not Fidelity.FINE:
        return result
    return _with_fea(design, result)


def _with_fea(design: PrrrDesign, result: Strength) -> Strength:
    """``result`` with the FEA's per-part stress and the frame's for the FEA's case (fine)."""
    from hapticopt.analysis.prrr.structure import stiffness
    from hapticopt.design.prrr.cad import DEFAULT_BRANCH

    fea_result = _fea(design)
    if fea_result is None or fea_result.status is not Status.OK:
        return replace(result, status=Status.FAILED, message="CAD FEA failed: no FEA stress to compare")
    st = stiffness.fea_element_stress(design, fea_result)
    fea = fea_part_stress(fea_result.mesh, st.von_mises)
    fp = fm.frame_params_of(design, xp=np)
    W = np.zeros((6, 1))
    W[0, 0], W[4, 0] = 1.0, fm.LOAD_HEIGHT  # 1 N along x at Δz: moment (Δz e_z) × e_x = Δz e_y
    frame, _ = part_stresses(fp, np.zeros(3), W, fm.FrameOptions(joints=fm.Joints.BONDED, branch=DEFAULT_BRANCH))
    return replace(result, fea_part_stress=fea, frame_part_stress_fea_case={k: float(v[0]) for k, v in frame.items()})


def _fea(design: PrrrDesign):
    """The fine level's CAD FEA of ``design`` with its fields (:func:`.fea_cad.fine_fea`: made once per
    process, shared with the stiffness evaluator), or None where it fails (the stiffness evaluator
    reports why)."""
    from hapticopt.analysis.prrr.structure import fea_cad

    try:
        return fea_cad.fine_fea(design)
    except Exception:  # noqa: BLE001 - CAD/gmsh failures: reported by the stiffness evaluator
        return None


def fea_part_stress(mesh, von_mises: np.ndarray) -> dict[str, float]:
    """Largest element (centroid) von Mises stress per part of the FEA mesh: an element belongs to the part
    whose node set holds its four vertices (the pins' and parts' volumes are meshed conformally: an element
    lies in one volume; one whose vertices all lie on a shared face counts for both)."""
    out = {}
    for name, nodes in mesh.node_sets.items():
        if name.startswith("support"):
            continue
        member = np.zeros(mesh.points.shape[1], dtype=bool)
        member[nodes] = True
        inside = np.all(member[mesh.tets], axis=0)
        if inside.any():
            out[name] = float(np.max(von_mises[inside]))
    return out
