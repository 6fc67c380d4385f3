"""hapticopt.analysis.loop.scene: bundled scenes, validation paths (one-line errors), effect resolution."""

from __future__ import annotations

import pytest

from hapticopt.analysis.loop.scene import (
    Backend,
    Effect,
    EnvKind,
    FrictionLocation,
    load_scene,
    resolve,
    scene_from_dict,
    scene_names,
)
from hapticopt.design import io
from hapticopt.design.errors import InputFileError, InvalidInput, UnknownName


def test_bundled_scenes_load_and_resolve():
    assert {"free-space", "stiffness-25", "virtual-box", "z-width"} <= set(scene_names())
    for name in scene_names():
        sc = load_scene(name)
        res = resolve(sc)
        # issue 8: link_dynamics and the master need the multibody plant, everything else is lumped
        needs_mb = sc.device == "master" or Effect.LINK_DYNAMICS in sc.effects
        assert res.backend == (Backend.MULTIBODY if needs_mb else Backend.LUMPED) and res.reason
    assert resolve(load_scene("stiffness-25-links")).backend == Backend.MULTIBODY
    st = load_scene("stiffness-25")
    assert st.environment.kind == EnvKind.SPRING
    assert st.environment.stiffness[0] == pytest.approx(25e3)  # issue 6: K_x = 25 N/mm
    assert st.motion.frequency == 1.0 and st.motion.amplitude[0] == pytest.approx(4e-3)  # seed 002: 1 Hz, 4 mm
    assert load_scene("virtual-box").environment.half_size == pytest.approx((0.01,) * 3)


def test_link_dynamics_needs_multibody_backend():
    sc = scene_from_dict({"name": "s", "effects": {"link_dynamics": True}})
    with pytest.raises(InvalidInput, match="link_dynamics requires the multibody backend"):
        resolve(sc, available=frozenset({Backend.LUMPED}))
    res = resolve(sc)
    assert res.backend == Backend.MULTIBODY and "link_dynamics" in res.reason and "gravity" in res.reason
    no_g = scene_from_dict({"name": "s", "effects": {"link_dynamics": True, "gravity": False}})
    assert "gravity" not in resolve(no_g).reason


def test_backend_forcing_from_scene_and_caller():
    """Forcing: multibody on a lumped-capable scene says so; lumped on link_dynamics / the master is refused."""
    sc = scene_from_dict({"name": "s", "backend": "multibody"})
    res = resolve(sc)
    assert res.backend == Backend.MULTIBODY and "forced" in res.reason
    assert resolve(sc, force=Backend.LUMPED).backend == Backend.LUMPED  # the caller wins
    with pytest.raises(InvalidInput, match="backend = lumped cannot simulate link_dynamics"):
        resolve(scene_from_dict({"name": "s", "backend": "lumped", "effects": {"link_dynamics": True}}))
    with pytest.raises(InvalidInput, match="backend = lumped cannot simulate the master"):
        resolve(scene_from_dict({"name": "s", "device": "master"}), force=Backend.LUMPED)
    with pytest.raises(InvalidInput, match="backend = 'mujoco' is not known"):
        scene_from_dict({"name": "s", "backend": "mujoco"})


def test_viscous_dropped_without_motor():
    sc = scene_from_dict({"name": "s", "effects": {"motor_dynamics": False}})
    res = resolve(sc)
    assert Effect.VISCOUS_FRICTION not in res.effects and any("viscous" in n for n in res.notes)


@pytest.mark.parametrize("data, match", [
    ({"name": "s", "duration_s": -1.0}, r"duration_s = -1 is out of range"),
    ({"name": "s", "controller": {"period_ms": "1"}}, r"controller.period_ms = '1' must be a finite number"),
    ({"name": "s", "environment": {"kind": "sprng"}}, r"environment.kind = 'sprng' is not known: allowed free"),
    ({"name": "s", "environment": {"stiffness_N_per_mm": [1, 2]}}, r"must be a list of 3 finite numbers"),
    ({"name": "s", "effects": {"gravity": 1}}, r"effects.gravity = 1 must be true or false"),
    ({"name": "s", "effects": {"warp_drive": True}}, r"effects.warp_drive is not a known key"),
    ({"name": "s", "effects": {"time_delay": True, "time_delay_ms": 1.5}}, r"whole number of controller periods"),
    ({"name": "s", "environment": {"kind": "free", "stiffness_N_per_mm": [1, 0, 0]}}, r"renders zero impedance"),
    ({"name": ""}, r"name = '' must be a non-empty string"),
    ({"name": "s", "simulation": {"measure_axis": "w"}}, r"is not an axis"),
])
def test_validation_messages(data, match):
    with pytest.raises(InvalidInput, match=match) as exc:
        scene_from_dict(data)
    assert "\n" not in str(exc.value)


def test_unknown_scene_and_missing_file(tmp_path):
    with pytest.raises(UnknownName, match="scene 'nope' does not exist"):
        load_scene("nope")
    with pytest.raises(InputFileError, match="does not exist"):
        load_scene(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = [")
    with pytest.raises(InputFileError, match="not valid TOML"):
        load_scene(bad)


def test_master_scenes_and_sweep_validation():
    """issue 8: master scenes are multibody, drop the SEA (no series spring) and validate their sweep."""
    sc = load_scene("master-transparency")
    assert sc.device == "master" and sc.sweep_factors == (0.85, 0.95, 1.05, 1.15)
    assert sc.environment.stiffness[0] == pytest.approx(50.0)  # 0.05 N/mm (seed 003)
    assert not sc.controller.gravity_compensation
    res = resolve(scene_from_dict({"name": "m", "device": "master"}))
    assert res.backend == Backend.MULTIBODY and Effect.SEA_COMPLIANCE not in res.effects
    assert any("series spring" in n for n in res.notes)
    with pytest.raises(InvalidInput, match="simulation.sweep_factors"):
        scene_from_dict({"name": "m", "simulation": {"sweep_factors": [1.0]}})
    with pytest.raises(InvalidInput, match="device = 'robot' is not known"):
        scene_from_dict({"name": "m", "device": "robot"})


def test_handle_scenes_and_interpolation_variant():
    from hapticopt.analysis.control.upsampling import DEFAULT_VARIANT, Variant

    sc = load_scene("handle-ball")
    assert sc.device == "handle" and sc.controller.interpolation_variant is DEFAULT_VARIANT
    res = resolve(sc)
    assert res.backend == Backend.LUMPED and res.effects == frozenset({Effect.SAMPLING, Effect.OPERATOR})
    assert res.notes and res.notes[0].startswith("not modelled on the handle, dropped: coulomb_friction")
    with pytest.raises(InvalidInput, match="backend = multibody cannot simulate the handle"):
        resolve(sc, force=Backend.MULTIBODY)
    v = scene_from_dict({"name": "s", "controller": {"interpolation_variant": "as_printed"}})
    assert v.controller.interpolation_variant is Variant.AS_PRINTED
    with pytest.raises(InvalidInput, match=r"controller.interpolation_variant = 'late' is not known: allowed none, "
                                           r"as_printed, as_intended"):
        scene_from_dict({"name": "s", "controller": {"interpolation_variant": "late"}})


# ------------------------------------------------------------------------- seed 001: IOIC mode
def _ioic(**over):
    d = {"name": "s", "controller": {"mode": "ioic"}, "operator": {"kind": "force_eq2"},
         "motion": {"shape": "square", "amplitude_mm": [10.0, 0.0, 0.0], "frequency_Hz": 0.25}}
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(d.get(k), dict):
            d[k] = {**d[k], **v}
        else:
            d[k] = v
    return d


def test_ioic_scenes_parse_with_seed001_defaults():
    """The bundled IOIC scenes: eq-2 operator with §4.1's gains, K_0 of eq 31 = [10, 4, 0.2] from
    M_0 = 5 kg, B_0 = 20 N·s/m, K_0 = 50 N/m, Q = I and R = 0.01 of eq 27, 0.5 s / 50 intervals."""
    from hapticopt.analysis.loop.operator import OperatorKind
    from hapticopt.analysis.loop.scene import FirmwareMode, IoicStrategy, MotionShape

    for name, device in (("master-ioic", "master"), ("prrr-ioic", "prrr")):
        sc = load_scene(name)
        assert sc.device == device and sc.controller.mode == FirmwareMode.IOIC
        op = sc.operator
        assert op.kind == OperatorKind.FORCE_EQ2
        assert (op.force_time_constant, op.force_decay, op.force_gain) == (0.5, 5.0, 20.0)
        s = sc.ioic
        assert s.strategy == IoicStrategy.IOIC and s.axis == 0
        assert s.initial_gain == pytest.approx((10.0, 4.0, 0.2), rel=1e-15)
        assert s.state_weights == (1.0, 1.0, 1.0) and s.input_weight == 0.01
        assert (s.learn_time, s.intervals, s.switch_time, s.exploration) == (0.5, 50, 0.5, True)
        assert sc.motion.shape == MotionShape.SQUARE
    nt = load_scene("master-ioic").ntsmtc  # seed 001 §4.2
    assert (nt.lambda1, nt.lambda2, nt.a, nt.b, nt.mu, nt.eta) == ((3.0,) * 3, (3.0,) * 3, 5, 3, 0.005, 1.5)


def test_square_motion_starts_high():
    """Seed 001 §4.1: x_d = +amplitude on the first half period, −amplitude on the second."""
    m = scene_from_dict(_ioic()).motion
    assert [m.square(t) for t in (0.0, 1.0, 1.999, 2.0, 3.9, 4.0)] == [1.0, 1.0, 1.0, -1.0, -1.0, 1.0]


@pytest.mark.parametrize("over,match", [
    ({"controller": {"mode": "impedance"}}, r'operator.kind = .force_eq2. with controller.mode = .impedance.'),
    ({"operator": {"kind": "mass_spring_damper"}}, r"operator.kind = 'mass_spring_damper' with controller.mode = 'ioic'"),
    ({"operator": {"kind": "robot"}}, r"operator.kind = 'robot' is not known: allowed mass_spring_damper, force_eq2"),
    ({"operator": {"mass_kg": 0.3}}, r"operator.mass_kg is not a known key: allowed force_decay, force_gain_N_per_m"),
    ({"operator": {"force_decay": 0}}, r"operator.force_decay = 0 is out of range: allowed 0 < force_decay"),
    ({"ioic": {"intervals": 1000}}, r"ioic.intervals = 1000 gives intervals of 0.5 ms, shorter than the controller"),
    ({"ioic": {"noise_seed": -3}}, r"ioic.noise_seed = -3 must be a whole number"),
    ({"ioic": {"initial_mass_kg": 0}}, r"ioic.initial_mass_kg = 0 is out of range: allowed 0 < initial_mass_kg"),
    ({"ioic": {"strategy": "lqr"}}, r"ioic.strategy = 'lqr' is not known: allowed fic, oic, ioic"),
    ({"ntsmtc": {"a": 4}}, r"ntsmtc.a = 4, ntsmtc.b = 3 must be odd with 1/2 < b/a < 1 \(seed 001 eq 14\)"),
    ({"ntsmtc": {"a": 5}}, r"\[ntsmtc\] is the master's inner loop"),
    ({"device": "master", "ioic": {"tracking_stiffness_N_per_mm": 3.0}}, r"ioic.tracking_\* set the 3-PRRR's"),
    ({"effects": {"operator": False}}, r"effects.operator = false: controller.mode = .ioic. learns"),
])
def test_ioic_validation_messages(over, match):
    with pytest.raises(InvalidInput, match=match):
        scene_from_dict(_ioic(**over))


def test_ioic_tables_only_in_ioic_mode():
    with pytest.raises(InvalidInput, match=r'\[ioic\] is read only with controller.mode = "ioic"'):
        scene_from_dict({"name": "s", "ioic": {"learn_s": 1.0}})
    with pytest.raises(InvalidInput, match=r"motion.shape = 'square' drives the eq-2 operator only"):
        scene_from_dict({"name": "s", "motion": {"shape": "square"}})


def test_impedance_simulators_refuse_ioic_scenes():
    from hapticopt.analysis.prrr.loop import closed_loop
    from hapticopt.design.io import load_preset

    with pytest.raises(InvalidInput, match=r"controller.mode = 'ioic' is not run by the 3-PRRR's impedance firmware"):
        closed_loop.setup(load_preset("prrr-paper"), load_scene("prrr-ioic"))


def test_master_protocol_scenes_and_dynamics_compensation_key():
    """issue 16: seed 003's protocol scenes (7.5 mm at 1 Hz for 3 s, links compensated, no gravity
    compensation); controller.dynamics_compensation accepts none / links / full only."""
    from hapticopt.analysis.loop.scene import DynamicsCompensation

    for axis, amp in (("x", (7.5e-3, 0.0, 0.0)), ("z", (0.0, 0.0, 7.5e-3))):
        sc = load_scene(f"master-protocol-{axis}")
        assert sc.motion.amplitude == pytest.approx(amp) and sc.motion.frequency == pytest.approx(1.0)
        assert sc.duration == pytest.approx(3.0) and not sc.controller.gravity_compensation
        assert sc.controller.dynamics_compensation is DynamicsCompensation.LINKS
    assert load_scene("master-wall").controller.dynamics_compensation is DynamicsCompensation.NONE
    with pytest.raises(InvalidInput, match="dynamics_compensation = 'model' is not known: allowed none, links, full"):
        scene_from_dict({"name": "m", "device": "master", "controller": {"dynamics_compensation": "model"}})


def test_seed002_experiment_scenes_parse():
    """Issue 19: the paper's protocols as scenes (units in keys, SI inside)."""
    import math

    from hapticopt.analysis.loop.scene import FrictionLocation, PaperQuantity, load_scene

    fx = load_scene("free-space-x")
    assert fx.friction_location == FrictionLocation.R_JOINTS and fx.motion.amplitude == pytest.approx((4e-3, 0, 0))
    assert fx.report.quantity == PaperQuantity.HAND_FORCE_AXIS_RMS and fx.report.value == 0.50
    assert load_scene("free-space-y-2hz").motion.frequency == 2.0
    circle = load_scene("force-circle-xy")
    assert circle.environment.force_phase == pytest.approx((0.0, math.pi / 2, 0.0))
    assert circle.output_locked and circle.report.axes == (0, 1)
    track = load_scene("force-tracking")
    assert track.report.axes == (2,) and track.environment.force_frequency == 3.0
    assert load_scene("free-space").friction_location == FrictionLocation.SLIDERS  # the default is unchanged


@pytest.mark.parametrize("name", ["free-space-x", "free-space-y", "free-space-x-2hz", "free-space-y-2hz",
                                  "force-tracking", "force-circle-xy", "force-circle-xz", "stiffness-25"])
def test_seed002_scenes_run_at_the_papers_gain_and_list_what_they_assume(name):
    """Issue 30: every seed-002 scene at the paper's stated K_p = 45, and every value the paper does not
    give (the loop rate at least; τ_c and the operator where the scene has them) listed with a source."""
    sc = load_scene(name)
    keys = {a.key for a in sc.report.assumptions}
    assert sc.controller.force_gain == 45.0 and {"controller.period_ms", "controller.force_gain"} <= keys
    if sc.friction_location == FrictionLocation.R_JOINTS:
        assert "design.structure.joint_friction_Nm" in keys
    if Effect.OPERATOR in resolve(sc).effects:  # a locked output has no operator
        assert "operator.stiffness_N_per_mm" in keys
    assert all(a.source.strip() for a in sc.report.assumptions)


def test_assumptions_report_the_values_the_run_uses():
    """The listed value is read from the run's scene (after an override) and from the design."""
    import dataclasses

    from hapticopt.analysis.loop import assumptions

    sc = load_scene("free-space-x")
    sc = dataclasses.replace(sc, controller=dataclasses.replace(sc.controller, period=0.5e-3))
    d = io.apply_overrides(io.load_preset("prrr-paper"), ["structure.joint_friction_Nm=0.05"])
    got = {a["key"]: a["value"] for a in assumptions.values(sc.report.assumptions, sc, d)}
    assert got["controller.period_ms"] == pytest.approx(0.5) and got["design.structure.joint_friction_Nm"] == 0.05
    assert got["operator.stiffness_N_per_mm"] == pytest.approx(20.0)


@pytest.mark.parametrize("extra, match", [
    ({"effects": {"friction_location": "hinges"}}, "friction_location = 'hinges' is not known: allowed sliders"),
    ({"report": {"axes": "x"}}, "report.quantity is missing"),
    ({"report": {"quantity": "rms"}}, "report.quantity = 'rms' is not known"),
    ({"report": {"quantity": "force_error_plane_rms", "axes": "x"}}, "must name a plane"),
    ({"report": {"quantity": "hand_force_axis_rms", "axes": "xy"}}, "must name one axis"),
    ({"report": {"quantity": "hand_force_axis_rms", "axes": "xx"}}, "must name one or two different axes"),
    ({"report": {"quantity": "hand_force_axis_rms", "paper_value_N": -1}}, "paper_value_N = -1 must be a finite"),
    ({"report": {"quantity": "stiffness_error_pct", "paper_value_N": 6.6}}, "report.paper_value_N is not a known key"),
    ({"environment": {"kind": "force", "force_phase_deg": [0, 400, 0]}}, "force_phase_deg = [0, 400, 0] is out of range"),
    ({"report": {"quantity": "hand_force_axis_rms", "assumptions": {"key": "controller.period_ms"}}},
     "report.assumptions = "),
    ({"report": {"quantity": "hand_force_axis_rms", "assumptions": [{"key": "controller.period_ms"}]}},
     "report.assumptions[0] = "),
    ({"report": {"quantity": "hand_force_axis_rms", "assumptions": [{"key": "controller.period_ms", "source": " "}]}},
     "report.assumptions[0].source = ' ' must be a non-empty string"),
    ({"report": {"quantity": "hand_force_axis_rms", "assumptions": [{"key": "controller.rate", "source": "x"}]}},
     "report.assumptions[0].key = 'controller.rate' is not a key an assumption can name"),
])
def test_seed002_scene_validation(extra, match):
    with pytest.raises(InvalidInput, match=match.replace("[", r"\[").replace("]", r"\]")):
        scene_from_dict({"name": "s", **extra})


@pytest.mark.parametrize("ctl, match", [
    ({"predictor": "psychic"}, r"controller.predictor = 'psychic' is not known: allowed fixed, online"),
    ({"ar_order": 2}, r"ar_order / ar_window apply to predictor = \"online\" only"),
    ({"predictor": "online", "ar_coefficients": [2, -1]}, r"ar_coefficients = \[2, -1\] applies to predictor = \"fixed\" only"),
    ({"predictor": "online", "ar_order": 4, "ar_window": 7}, r"ar_window = 7 is out of range: allowed ≥ 2·ar_order = 8"),
    ({"predictor": "online", "ar_order": 17}, r"ar_order = 17 must be a whole number: allowed 1 ≤ ar_order ≤ 16"),
])
def test_predictor_keys_are_checked(ctl, match):
    with pytest.raises(InvalidInput, match=match):
        scene_from_dict({"name": "t", "device": "handle", "controller": ctl})


def test_the_3prrr_online_predictor_window_is_checked():
    # the 3-PRRR's defaults are AR(2) over 16 positions; an order whose 2·p exceeds the window is one line
    from hapticopt.analysis.prrr.loop import firmware
    sc = scene_from_dict({"name": "t", "controller": {"predictor": "online", "interpolation": 4}})
    cfg, _ = firmware.build(io.load_preset("prrr-paper"), sc, resolve(sc))
    assert cfg.online and (cfg.ar_order, cfg.ar_window) == (2, 16)
    sc = scene_from_dict({"name": "t", "controller": {"predictor": "online", "interpolation": 4, "ar_order": 9}})
    with pytest.raises(InvalidInput, match=r"^scene t: controller.ar_window = 16 is out of range: allowed ≥ 2·ar_order = 18"):
        firmware.build(io.load_preset("prrr-paper"), sc, resolve(sc))
