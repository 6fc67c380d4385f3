"""The 3-PRRR constant-Jacobian translational parallel robot driven by SEAs (seed 002).

Three vertical prismatic (P) joints at γ = 0, +2π/3, −2π/3 about the z axis, each followed by
three revolute joints with parallel axes inclined at β to the xy plane. Geometry follows a leg
construction consistent with seed 002's eq (1) and its constant c_e (``docs/workspace.md``;
the papers: ``docs/references.md``). All values are SI; TOML keys carry engineering units.

Slider stroke convention (the paper does not state its zero): the stroke of length
``stroke`` is centred on the slider position of the home pose p = 0, so every slider
travels D ∈ [c_e − L/2, c_e + L/2], with c_e the eq (1) offset.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from hapticopt.design import materials
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.schema import choice, param, validate_section

DEVICE = "prrr"
#: Leg directions γ_i (seed 002, eq 2: γ1 = 0, γ2 = +2π/3, γ3 = −2π/3).
GAMMAS: tuple[float, float, float] = (0.0, 2.0 * math.pi / 3.0, -2.0 * math.pi / 3.0)

_LEN = dict(lo=0.0, hi=2000.0, lo_open=True)

#: θ_1p of ``prrr-paper`` [deg]: seed 002 defines θ_1p (the first P joint's angle from u_11) but
#: Table 2 omits its value. Derived in :func:`hapticopt.design.prrr.cad.carried_theta_1p` from the
#: paper's intent, R1 carried directly by the carriage (docs/cad.md, "Rail placement θ_1p"); the
#: value here is that function's result for the Table 2 geometry and the preset's part sizes,
#: rounded to 0.1 deg (a test recomputes it).
THETA_1P_PAPER_DEG = 83.0


@dataclass(frozen=True, kw_only=True)
class PrrrGeometry:
    """Kinematic geometry (seed 002 Table 2 defaults)."""

    beta: float = param("beta_deg", "deg", default=60.0, lo=0.0, hi=90.0, lo_open=True, hi_open=True,
                        doc="inclination of the R-joint axes to the xy plane")
    r_p: float = param("r_p_mm", "mm", default=100.0, **_LEN, doc="distance of each P joint (rail) from the z axis")
    d1: float = param("d1_mm", "mm", default=30.0, **_LEN, doc="radial offset of R1 from the z axis")
    d2: float = param("d2_mm", "mm", default=88.75, **_LEN, doc="tangential offset of R1")
    d3: float = param("d3_mm", "mm", default=80.0, **_LEN, doc="R1–R2 link length")
    d4: float = param("d4_mm", "mm", default=80.0, **_LEN, doc="R2–R3 link length (in-plane)")
    r4: float = param("r4_mm", "mm", default=20.0, **_LEN, doc="R2–R3 link offset along the joint axis")
    b5: float = param("b5_mm", "mm", default=40.0, **_LEN, doc="R3 offset from the end-effector along the axis; r5 = b5·sin β")
    stroke: float = param("stroke_mm", "mm", default=170.0, **_LEN, doc="slider stroke, centred on the home pose")
    theta_1p: float = param("theta_1p_deg", "deg", default=THETA_1P_PAPER_DEG, lo=-180.0, hi=180.0,
                            doc="angle of rail i (P joint, carriage, SEA module) from u_i about z; "
                                "eq 1 does not depend on it (seed 002 θ_1p)")

    @property
    def r5(self) -> float:
        """Vertical offset of R3 from the end-effector centre [m] (r5 = b5·sin β, seed 002)."""
        return self.b5 * math.sin(self.beta)

    @property
    def c_e(self) -> float:
        """Slider offset of eq (1) [m]: c_e = −(b5 + r4)/sin β + r5 + d1·cot β."""
        return -(self.b5 + self.r4) / math.sin(self.beta) + self.r5 + self.d1 / math.tan(self.beta)


@dataclass(frozen=True, kw_only=True)
class SeaActuator:
    """Series-elastic actuator per leg (seed 002 Table 4; eq 3, 6)."""

    spring: float = param("spring_N_per_mm", "N_per_mm", default=56.27, lo=0.0, hi=1e6, lo_open=True,
                          doc="SEA spring stiffness k")
    force_limit: float = param("force_limit_N", "N", default=3581.0 / 3.0, lo=0.0, hi=1e6, lo_open=True,
                               doc="per-actuator force limit F_max (Table 1 z force / 3)")
    motor_mass: float = param("motor_mass_kg", "kg", default=81.736, lo=0.0, hi=1e5, lo_open=True,
                              doc="equivalent input mass M_m (rotor + screw reflected)")
    viscous: float = param("viscous_Ns_per_m", "Ns_per_m", default=9705.4, lo=0.0, hi=1e7,
                           doc="equivalent screw viscous friction ξ")
    efficiency: float = param("efficiency", "", default=0.9173, lo=0.0, hi=1.0, lo_open=True,
                              doc="motor-force factor η (screw Coulomb loss)")
    coulomb_friction: float = param("coulomb_friction_N", "N", default=3.0, lo=0.0, hi=1e4,
                                    doc="Coulomb friction per slider (assumed; seed 002 compensates 3 N)")
    encoder_resolution: float = param("encoder_resolution_um", "um", default=1.25, lo=0.0, hi=1e4, lo_open=True,
                                      doc="spring-deflection and slider encoder resolution (Table 1)")


@dataclass(frozen=True, kw_only=True)
class EndEffector:
    """End-effector (seed 002 Table 4: M includes the links as a point mass)."""

    mass: float = param("mass_kg", "kg", default=0.66, lo=0.0, hi=1e3, lo_open=True,
                        doc="equivalent end-effector mass M")
    handle_diameter: float = param("handle_diameter_mm", "mm", default=30.0, lo=0.0, hi=500.0, lo_open=True,
                                   doc="handle ball diameter")


def _material_fields(name: str) -> dict[str, float]:
    """The numeric fields of :class:`Structure` a named material sets [SI]."""
    m = materials.material(name)
    return {"density": m.density, "youngs_modulus": m.youngs_modulus, "poisson_ratio": m.poisson_ratio}


@dataclass(frozen=True, kw_only=True)
class Structure:
    """Cross-sections and material of the links (not given in seed 002; documented defaults)."""

    link_width: float = param("link_width_mm", "mm", default=20.0, lo=0.0, hi=500.0, lo_open=True,
                              doc="link cross-section, in-plane width")
    link_thickness: float = param("link_thickness_mm", "mm", default=10.0, lo=0.0, hi=500.0, lo_open=True,
                                  doc="link cross-section, thickness along the joint axis")
    boss_diameter: float = param("boss_diameter_mm", "mm", default=24.0, lo=0.0, hi=500.0, lo_open=True,
                                 doc="joint boss outer diameter")
    bore_diameter: float = param("bore_diameter_mm", "mm", default=8.0, lo=0.0, hi=500.0, lo_open=True,
                                 doc="joint pin bore diameter")
    material: str = choice("material", default="6061-T6", check=lambda v, where: materials.material(v, where),
                           fills=lambda name: _material_fields(name),
                           doc="material of the mechanism's parts (links, carriage brackets, platform, pins): a name "
                               "of design/materials.toml; sets density and moduli unless the table gives them, and "
                               "the strength check reads its yield and fatigue strength")
    density: float = param("density_kg_per_m3", "kg_per_m3", default=2700.0, lo=0.0, hi=25000.0, lo_open=True,
                           doc="material density (aluminium 6061)")
    youngs_modulus: float = param("youngs_modulus_GPa", "GPa", default=68.9, lo=0.0, hi=1500.0, lo_open=True,
                                  doc="Young's modulus (aluminium 6061)")
    poisson_ratio: float = param("poisson_ratio", "", default=0.33, lo=0.0, hi=0.5, hi_open=True,
                                 doc="Poisson's ratio (aluminium 6061)")
    # --- CAD (design/prrr/cad.py); defaults chosen here, the paper gives no part data
    clearance: float = param("clearance_mm", "mm", default=0.5, lo=0.0, hi=50.0, lo_open=True,
                             doc="axial gap between stacked links at a joint")
    rail_width: float = param("rail_width_mm", "mm", default=20.0, lo=0.0, hi=500.0, lo_open=True,
                              doc="square cross-section of each vertical slider rail")
    carriage_height: float = param("carriage_height_mm", "mm", default=50.0, lo=0.0, hi=1000.0, lo_open=True,
                                   doc="height of the carriage block along the rail")
    carriage_wall: float = param("carriage_wall_mm", "mm", default=8.0, lo=0.0, hi=500.0, lo_open=True,
                                 doc="wall of the carriage block around the rail")
    sea_envelope: float = param("sea_envelope_mm", "mm", default=25.0, lo=0.0, hi=1000.0, lo_open=True,
                                doc="radial depth of the SEA housing envelope outside the rail")
    base_radius: float = param("base_radius_mm", "mm", default=140.0, lo=0.0, hi=5000.0, lo_open=True,
                               doc="radius of the base plate")
    base_thickness: float = param("base_thickness_mm", "mm", default=10.0, lo=0.0, hi=500.0, lo_open=True,
                                  doc="thickness of the base plate")
    base_clearance: float = param("base_clearance_mm", "mm", default=5.0, lo=0.0, hi=500.0,
                                  doc="gap between the lowest carriage and the base plate")
    stem_diameter: float = param("stem_diameter_mm", "mm", default=10.0, lo=0.0, hi=500.0, lo_open=True,
                                 doc="diameter of the end-effector stem carrying the handle ball")
    joint_friction: float = param("joint_friction_Nm", "Nm", default=0.0384, lo=0.0, hi=100.0,
                                  doc="Coulomb friction torque of each R joint (assumed: its x-equivalent at home, "
                                      "0.0384 N·m × 78.06 rad/m, is the 3 N seed 002 compensates)")


@dataclass(frozen=True, kw_only=True)
class SeaModule:
    """Physical parts of each leg's SEA drive (seed 002 Fig. 3: motor, belt, ball screw, spring
    housing; the paper gives no sizes or masses: approximate envelopes and catalogue-class masses,
    docs/cad.md "Device size and mass"). The equivalent masses of :class:`SeaActuator` (eq 3, 6)
    are dynamics parameters and unrelated to these."""

    motor_diameter: float = param("motor_diameter_mm", "mm", default=32.0, lo=0.0, hi=500.0, lo_open=True,
                                  doc="motor housing diameter (vertical, on the base plate beside the rail)")
    motor_length: float = param("motor_length_mm", "mm", default=60.0, lo=0.0, hi=1000.0, lo_open=True,
                                doc="motor housing length with encoder and belt pulley")
    motor_radial_offset: float = param("motor_radial_offset_mm", "mm", default=-8.0, lo=-500.0, hi=500.0,
                                       doc="radial offset of the motor axis from the rail axis (negative: towards z)")
    motor_mass: float = param("motor_mass_kg", "kg", default=0.30, lo=0.0, hi=100.0, lo_open=True,
                              doc="motor with encoder, pulleys and belt")
    screw_diameter: float = param("screw_diameter_mm", "mm", default=8.0, lo=0.0, hi=200.0, lo_open=True,
                                  doc="ball screw diameter (parallel to the rail, inside the spring housing)")
    screw_mass: float = param("screw_mass_kg", "kg", default=0.10, lo=0.0, hi=100.0, lo_open=True,
                              doc="ball screw with its end bearings")
    housing_mass: float = param("housing_mass_kg", "kg", default=0.15, lo=0.0, hi=100.0, lo_open=True,
                                doc="spring housing with springs, nut and deflection encoder (moves with the carriage)")


@dataclass(frozen=True, kw_only=True)
class PrrrDesign:
    """A complete 3-PRRR design. Frozen; change with :func:`dataclasses.replace`."""

    name: str = "prrr"
    description: str = ""
    geometry: PrrrGeometry = field(default_factory=PrrrGeometry)
    actuator: SeaActuator = field(default_factory=SeaActuator)
    end_effector: EndEffector = field(default_factory=EndEffector)
    structure: Structure = field(default_factory=Structure)
    sea_module: SeaModule = field(default_factory=SeaModule)

    device = DEVICE  # class constant, not a field

    SECTIONS = ("geometry", "actuator", "end_effector", "structure", "sea_module")

    def __post_init__(self) -> None:
        validate(self)


def validate(design: PrrrDesign) -> None:
    """Check every field's range and the cross-field rules; raise :class:`InvalidDesign`."""
    for section in PrrrDesign.SECTIONS:
        validate_section(getattr(design, section), section)
    s = design.structure
    if s.bore_diameter >= s.boss_diameter:
        raise InvalidDesign(
            f"structure.bore_diameter_mm = {s.bore_diameter * 1e3:g} must be smaller than "
            f"structure.boss_diameter_mm = {s.boss_diameter * 1e3:g} (mm)"
        )


def with_material(design: PrrrDesign, name: str) -> PrrrDesign:
    """``design`` with its mechanism made of library material ``name``: the material and its density,
    Young's modulus and Poisson's ratio together (the discrete outer loop's step, docs/strength.md)."""
    return dataclasses.replace(design, structure=dataclasses.replace(design.structure, material=name,
                                                                     **_material_fields(name)))


def replace(design: PrrrDesign, **sections: object) -> PrrrDesign:
    """``dataclasses.replace`` re-exported for symmetry with section updates."""
    return dataclasses.replace(design, **sections)
