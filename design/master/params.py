"""PHANToM-type surgical haptic master with counterweights (seed 003).

Joints: θ1 rotates the turret about the vertical axis; θ2 drives the upper arm (length L5 in
seed 003) and θ3 drives the forearm (length L4) through a parallelogram, so the forearm angle
is set directly by θ3. Counterweights sit on the rear extensions of the two driven links:
``counterweights.upper_*`` behind the shoulder on the upper arm's extension (m2 at r2x in
seed 003) and ``counterweights.forearm_*`` on the rear of the θ3 driver link (m4 at r4z).

Joint ranges default to the paper's workspace: −90° < θ3 < 40° and
35° < 90° − θ2 + θ3 < 150° (seed 003), giving a workspace of about a 200 mm cube with the
link lengths below. Defaults = the preset master-paper, re-derived from seed 003 eq 7/12
(moving mass 1.30 kg, unbalance radius 0.81 mm; docs/master.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hapticopt.design.errors import InvalidDesign
from hapticopt.design.schema import param, validate_section

DEVICE = "master"

_LEN = dict(lo=0.0, hi=2000.0, lo_open=True)
_MASS = dict(lo=0.0, hi=100.0)


@dataclass(frozen=True, kw_only=True)
class MasterGeometry:
    """Link lengths (seed 003: L4 = L5 = 264 mm put the unbalance radius at 0.81 mm with M = 1.30 kg)."""

    upper_arm: float = param("upper_arm_mm", "mm", default=264.0, **_LEN, doc="shoulder (θ2 axis) to elbow, L5")
    forearm: float = param("forearm_mm", "mm", default=264.0, **_LEN, doc="elbow to handle centre, L4")
    driver_link: float = param("driver_link_mm", "mm", default=60.0, **_LEN,
                               doc="θ3 driver link of the parallelogram (short side)")
    shoulder_height: float = param("shoulder_height_mm", "mm", default=460.0, **_LEN,
                                   doc="height of the θ2/θ3 axes above the base plate")


@dataclass(frozen=True, kw_only=True)
class MasterLinks:
    """Masses and centres of mass of the moving links (CoM measured along each link from its proximal joint)."""

    upper_arm_mass: float = param("upper_arm_mass_kg", "kg", default=0.565, **_MASS,
                                 doc="upper arm with its capstan drum sector")
    upper_arm_com: float = param("upper_arm_com_mm", "mm", default=-35.4, lo=-2000.0, hi=2000.0)
    forearm_mass: float = param("forearm_mass_kg", "kg", default=0.050, **_MASS)
    forearm_com: float = param("forearm_com_mm", "mm", default=100.0, lo=-2000.0, hi=2000.0)
    driver_link_mass: float = param("driver_link_mass_kg", "kg", default=0.500, **_MASS,
                                   doc="θ3 driver link with its capstan drum sector")
    driver_link_com: float = param("driver_link_com_mm", "mm", default=12.2, lo=-2000.0, hi=2000.0)
    coupler_mass: float = param("coupler_mass_kg", "kg", default=0.030, **_MASS,
                                doc="parallelogram coupler, parallel to the upper arm")
    coupler_com: float = param("coupler_com_mm", "mm", default=132.0, lo=-2000.0, hi=2000.0)
    handle_mass: float = param("handle_mass_kg", "kg", default=0.030, **_MASS, doc="handle/gimbal at the forearm tip")
    turret_inertia: float = param("turret_inertia_kg_mm2", "kg_mm2", default=2000.0, lo=0.0, hi=1e9,
                                  doc="turret inertia about the θ1 axis")


@dataclass(frozen=True, kw_only=True)
class Counterweights:
    """Counterweights on the rear extensions of the driven links."""

    upper_mass: float = param("upper_mass_kg", "kg", default=0.0634875, **_MASS, doc="m2 (seed 003)")
    upper_distance: float = param("upper_distance_mm", "mm", default=80.0, lo=0.0, hi=2000.0,
                                  doc="behind the shoulder along the upper arm, r2x")
    forearm_mass: float = param("forearm_mass_kg", "kg", default=0.06275, **_MASS, doc="m4 (seed 003)")
    forearm_distance: float = param("forearm_distance_mm", "mm", default=80.0, lo=0.0, hi=2000.0,
                                    doc="behind the elbow drive axis along the driver link, r4z")


@dataclass(frozen=True, kw_only=True)
class MasterJoints:
    """Joint ranges (seed 003's workspace)."""

    theta1_min: float = param("theta1_min_deg", "deg", default=-60.0, lo=-180.0, hi=180.0)
    theta1_max: float = param("theta1_max_deg", "deg", default=60.0, lo=-180.0, hi=180.0)
    theta3_min: float = param("theta3_min_deg", "deg", default=-90.0, lo=-180.0, hi=180.0)
    theta3_max: float = param("theta3_max_deg", "deg", default=40.0, lo=-180.0, hi=180.0)
    parallelogram_min: float = param("parallelogram_min_deg", "deg", default=35.0, lo=0.0, hi=180.0,
                                     doc="lower limit of 90° − θ2 + θ3")
    parallelogram_max: float = param("parallelogram_max_deg", "deg", default=150.0, lo=0.0, hi=180.0,
                                     doc="upper limit of 90° − θ2 + θ3")


@dataclass(frozen=True, kw_only=True)
class MasterActuators:
    """Joint motors (capstan drives)."""

    torque_limit: float = param("torque_limit_Nm", "Nm", default=0.5, lo=0.0, hi=1e4, lo_open=True,
                                doc="per-joint continuous torque limit")
    rotor_inertia: float = param("rotor_inertia_kg_mm2", "kg_mm2", default=100.0, lo=0.0, hi=1e9,
                                 doc="reflected rotor + capstan inertia per joint")
    viscous: float = param("viscous_Nms_per_rad", "Nms_per_rad", default=1e-4, lo=0.0, hi=1e3,
                           doc="joint viscous friction")
    coulomb: float = param("coulomb_Nm", "Nm", default=0.0, lo=0.0, hi=1e3, doc="joint Coulomb friction")
    encoder_counts: float = param("encoder_counts_per_rev", "", default=40000.0, lo=1.0, hi=1e9, integer=True,
                                  doc="joint encoder counts per joint revolution (after the capstan: "
                                      "40000 → 0.041 mm at 0.264 m; PHANToM 1.5 class: 0.03 mm nominal resolution)")


@dataclass(frozen=True, kw_only=True)
class MasterStructure:
    """Cross-sections and materials of the CAD (design/master/cad.py); not in seed 003, documented defaults."""

    link_width: float = param("link_width_mm", "mm", default=14.0, lo=0.0, hi=500.0, lo_open=True,
                              doc="link cross-section, in the arm plane")
    link_thickness: float = param("link_thickness_mm", "mm", default=8.0, lo=0.0, hi=500.0, lo_open=True,
                                  doc="link cross-section, along the joint axis")
    boss_diameter: float = param("boss_diameter_mm", "mm", default=18.0, lo=0.0, hi=500.0, lo_open=True,
                                 doc="joint boss outer diameter")
    bore_diameter: float = param("bore_diameter_mm", "mm", default=6.0, lo=0.0, hi=500.0, lo_open=True,
                                 doc="joint pin bore diameter")
    light_link_width: float = param("light_link_width_mm", "mm", default=8.0, lo=0.0, hi=500.0, lo_open=True,
                                    doc="coupler and forearm cross-section, in the arm plane (light links: the "
                                        "model gives them 30 g and 50 g, below a 14 × 8 mm aluminium bar)")
    light_link_thickness: float = param("light_link_thickness_mm", "mm", default=4.0, lo=0.0, hi=500.0,
                                        lo_open=True, doc="coupler and forearm cross-section, along the joint axis")
    clearance: float = param("clearance_mm", "mm", default=0.5, lo=0.0, hi=50.0, lo_open=True,
                             doc="axial gap between stacked links at a joint")
    density: float = param("density_kg_per_m3", "kg_per_m3", default=2700.0, lo=0.0, hi=25000.0, lo_open=True,
                           doc="link material density (aluminium 6061)")
    counterweight_density: float = param("counterweight_density_kg_per_m3", "kg_per_m3", default=7850.0, lo=0.0,
                                         hi=25000.0, lo_open=True, doc="counterweight and ballast material (steel)")
    counterweight_length: float = param("counterweight_length_mm", "mm", default=20.0, lo=0.0, hi=500.0,
                                        lo_open=True, doc="counterweight and ballast disc length along the joint axis")
    turret_radius: float = param("turret_radius_mm", "mm", default=30.0, lo=0.0, hi=1000.0, lo_open=True,
                                 doc="radius of the turret drum")
    base_radius: float = param("base_radius_mm", "mm", default=110.0, lo=0.0, hi=5000.0, lo_open=True,
                               doc="radius of the base plate")
    base_thickness: float = param("base_thickness_mm", "mm", default=12.0, lo=0.0, hi=500.0, lo_open=True,
                                  doc="thickness of the base plate (below z = 0)")
    handle_diameter: float = param("handle_diameter_mm", "mm", default=25.0, lo=0.0, hi=500.0, lo_open=True,
                                   doc="handle ball diameter at the forearm tip")


@dataclass(frozen=True, kw_only=True)
class MasterDesign:
    """A complete surgical-master design. Frozen; change with :func:`dataclasses.replace`."""

    name: str = "master"
    description: str = ""
    geometry: MasterGeometry = field(default_factory=MasterGeometry)
    links: MasterLinks = field(default_factory=MasterLinks)
    counterweights: Counterweights = field(default_factory=Counterweights)
    joints: MasterJoints = field(default_factory=MasterJoints)
    actuators: MasterActuators = field(default_factory=MasterActuators)
    structure: MasterStructure = field(default_factory=MasterStructure)

    device = DEVICE

    SECTIONS = ("geometry", "links", "counterweights", "joints", "actuators", "structure")

    def __post_init__(self) -> None:
        validate(self)


def validate(design: MasterDesign) -> None:
    """Check every field's range and the cross-field rules; raise :class:`InvalidDesign`."""
    for section in MasterDesign.SECTIONS:
        validate_section(getattr(design, section), section)
    j = design.joints
    for lo, hi, key in (
        (j.theta1_min, j.theta1_max, "theta1"),
        (j.theta3_min, j.theta3_max, "theta3"),
        (j.parallelogram_min, j.parallelogram_max, "parallelogram"),
    ):
        if lo >= hi:
            raise InvalidDesign(
                f"joints.{key}_min_deg = {lo * 57.29577951308232:g} must be below "
                f"joints.{key}_max_deg = {hi * 57.29577951308232:g} (deg)"
            )
