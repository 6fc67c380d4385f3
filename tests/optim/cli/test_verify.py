"""``hapticopt verify``: JSON metrics, scene by name or path, one-line errors with exit code 2."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hapticopt.optim.cli import app

runner = CliRunner()


def test_verify_json_metrics(tmp_path):
    scene = tmp_path / "short.toml"
    scene.write_text('name = "short"\nduration_s = 1.0\n[environment]\nkind = "spring"\n'
                     'stiffness_N_per_mm = [25.0, 0, 0]\n[motion]\namplitude_mm = [4.0, 0, 0]\n')
    res = runner.invoke(app, ["verify", "--preset", "prrr-paper", "--scene", str(scene), "--json",
                              "--plots", str(tmp_path / "plots")])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    if importlib.util.find_spec("matplotlib") is not None:  # plots are optional (matplotlib is not a dependency)
        assert out["plots"] and all(Path(p).is_file() for p in out["plots"])
    m = out["metrics"]
    assert {"stable", "rendered_stiffness_N_per_mm", "stiffness_error_pct", "residual_force_rms_N", "backend",
            "effects"} <= set(m)
    assert m["stable"] is True and m["backend"] == "lumped"
    assert m["stiffness_error_pct"] <= 10.0  # issue 6 acceptance bound (seed 002 measured 6.6 %)


@pytest.mark.parametrize("args, match", [
    (["--scene", "nope"], "scene 'nope' does not exist"),
    (["--scene", "free-space", "--fidelity", "ultra"], "is not a fidelity level"),
])
def test_verify_errors_are_one_line(args, match):
    res = runner.invoke(app, ["verify", "--preset", "prrr-paper", *args])
    assert res.exit_code == 2
    assert match in res.output and res.output.count("\n") <= 1


def test_verify_link_dynamics_refused_or_multibody(tmp_path):
    scene = tmp_path / "ld.toml"
    scene.write_text('name = "ld"\nduration_s = 0.01\n[effects]\nlink_dynamics = true\n')
    res = runner.invoke(app, ["verify", "--preset", "prrr-paper", "--scene", str(scene), "--json"])
    if res.exit_code == 2:
        assert "link_dynamics requires the multibody backend" in res.output
    else:  # the multibody backend (issue 8) registered itself
        assert json.loads(res.stdout)["metrics"]["backend"] == "multibody"


def test_verify_master_wall_and_backend_option(tmp_path):
    """issue 8: `hapticopt verify --preset master-paper --scene master-wall` runs the master firmware on the
    MuJoCo master; --backend forces or refuses; a prrr scene on the master is a one-line error."""
    res = runner.invoke(app, ["verify", "--preset", "master-paper", "--scene", "master-wall", "--fidelity", "draft",
                              "--json"])
    assert res.exit_code == 0, res.output
    m = json.loads(res.stdout)["metrics"]
    assert m["backend"] == "multibody" and m["device"] == "master" and "master" in m["resolution_reason"]
    assert m["stable"] and m["constraint_health_ok"] and m["wall_penetration_mm"] > 0
    for args, match in ((["--preset", "master-paper", "--scene", "master-wall", "--backend", "lumped"],
                         "backend = lumped cannot simulate the master"),
                        (["--preset", "master-paper", "--scene", "stiffness-25"], "is written for the prrr device"),
                        (["--preset", "prrr-paper", "--backend", "mujoco"], "--backend = 'mujoco' is not a backend")):
        bad = runner.invoke(app, ["verify", *args])
        assert bad.exit_code == 2 and match in bad.output and bad.output.count("\n") <= 1
    scene = tmp_path / "short.toml"
    scene.write_text('name = "short"\nduration_s = 0.1\n[environment]\nkind = "spring"\n'
                     'stiffness_N_per_mm = [25.0, 0, 0]\n[motion]\namplitude_mm = [4.0, 0, 0]\n')
    forced = runner.invoke(app, ["verify", "--preset", "prrr-paper", "--scene", str(scene), "--backend", "multibody",
                                 "--fidelity", "draft", "--json"])
    assert forced.exit_code == 0, forced.output
    fm = json.loads(forced.stdout)["metrics"]
    assert fm["backend"] == "multibody" and "forced" in fm["backend_reason"] and fm["constraint_health_ok"]


def test_verify_handle_scenes():
    # seed 000's handle: the wall and the ball scenes through analysis/verify.py
    for scene in ("handle-wall", "handle-ball"):
        res = runner.invoke(app, ["verify", "--preset", "handle-paper", "--scene", scene, "--json"])
        assert res.exit_code == 0, res.output
        out = json.loads(res.stdout)
        assert out["status"] == "ok" and out["metrics"]["backend"] == "handle"
        assert out["metrics"]["interpolation_variant"] == "as_intended"
    wrong = runner.invoke(app, ["verify", "--preset", "handle-paper", "--scene", "stiffness-25"])
    assert wrong.exit_code == 2 and "is written for the prrr device" in wrong.output


@pytest.mark.parametrize("preset, scene, status, extra", [
    ("master-paper", "master-ioic", "ok", {"joint_torque_peak_Nm", "joint_error_peak_mrad", "constraint_health_ok"}),
    ("prrr-paper", "prrr-ioic", "not-met", {"motor_command_peak_N", "force_tracking_rms_N"}),
])
def test_verify_ioic_scenes(preset, scene, status, extra):
    """Issue 18: seed 001's IOIC firmware mode on both devices from the command line; the learned
    impedance against the Riccati optimum, tracking error, interaction force, device loads. Issue 31:
    the status judges each of M, B, K against the optimum (10 %): the master's are within ≈ 2 % (ok),
    the 3-PRRR's 21–27 % off (not-met, the three errors in the message; docs/seed001.md)."""
    res = runner.invoke(app, ["verify", "--preset", preset, "--scene", scene, "--json"])
    assert res.exit_code == (0 if status == "ok" else 3), res.output  # exit 3 unless the verdict is ok
    out = json.loads(res.stdout)
    m = out["metrics"]
    assert out["status"] == status and m["firmware_mode"] == "ioic" and m["learning_status"] == "ok"
    errs = [m[f"impedance_{k}_rel_error"] for k in ("mass", "damping", "stiffness")]
    assert all(abs(e) <= 0.10 for e in errs) == (status == "ok")
    assert {"impedance_mass_kg", "impedance_damping_Ns_per_m", "impedance_stiffness_N_per_m",
            "optimal_impedance_mass_kg", "optimal_impedance_damping_Ns_per_m", "optimal_impedance_stiffness_N_per_m",
            "gain_rel_error_to_optimum", "tracking_error_rms_mm", "interaction_force_rms_N",
            "impedance_error_rms_after_learning_mm"} | extra <= set(m)


def test_verify_ioic_bad_scene_is_one_line(tmp_path):
    scene = tmp_path / "bad.toml"
    scene.write_text('name = "bad"\n[operator]\nkind = "force_eq2"\n')
    res = runner.invoke(app, ["verify", "--preset", "prrr-paper", "--scene", str(scene)])
    assert res.exit_code == 2 and res.output.count("\n") <= 1
    assert "operator.kind = 'force_eq2' with controller.mode = 'impedance'" in res.output


def test_design_map_json_and_plot(tmp_path):
    """``hapticopt design-map``: one T, two K_p, the figure written where matplotlib exists."""
    args = ["design-map", "--preset", "prrr-paper", "--periods-ms", "1", "--force-gains", "45,600",
            "--duration-s", "0.6", "--json"]
    if importlib.util.find_spec("matplotlib") is not None:
        args += ["--plots", str(tmp_path)]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    m = json.loads(res.stdout)["metrics"]
    assert m["map_verdict"] == [["ok", "unstable"]]
    assert m["map_residual_N"][0][1] is None and m["map_residual_N"][0][0] > 0
    assert m["map_stiffness_limit_N_per_mm"][0][1] == 0.0  # the sampled force loop is lost at 1 kHz, K_p = 600
    if "--plots" in args:
        assert (tmp_path / "design-map-free-space-x.png").is_file()


@pytest.mark.parametrize("args, match", [
    (["design-map", "--preset", "prrr-paper", "--periods-ms", "1:0.1:x"], "--periods-ms = '1:0.1:x' must be"),
    (["design-map", "--preset", "prrr-paper", "--periods-ms", "0"], "period_ms = 0 is out of range"),
    (["design-map", "--preset", "prrr-paper", "--scene", "free-space"], "has no [report] quantity"),
    (["design-map", "--preset", "master-paper"], "the design map is the 3-PRRR's"),
    (["verify", "--preset", "prrr-paper", "--period-ms", "0"], "--period-ms = 0 is out of range: allowed 0.001 ≤ period_ms ≤ 100 ms"),
    # issue 37: 1e-300 passed validation and grew ~35 MB/s to a segfault; the design map's range (1 µs) and a tick bound
    (["verify", "--preset", "prrr-paper", "--period-ms", "1e-300"], "--period-ms = 1e-300 is out of range: allowed 0.001 ≤"),
    (["verify", "--preset", "prrr-paper", "--period-ms", "0.001"],
     "--period-ms = 0.001 gives 3e+06 controller ticks over the scene's 3 s: allowed at most 1e+06 (period_ms ≥ 0.003 ms"),
    (["verify", "--preset", "prrr-paper", "--force-gain", "-1"], "--force-gain = -1 is out of range"),
])
def test_design_map_and_overrides_errors_are_one_line(args, match):
    res = runner.invoke(app, args)
    assert res.exit_code == 2, res.output
    assert match in res.output and res.output.count("\n") <= 1


def test_verify_force_gain_override_changes_the_result():
    """--force-gain / --period-ms are first-class: the free-space residual falls with K_p (issue 19)."""
    def residual(*extra):
        res = runner.invoke(app, ["verify", "--preset", "prrr-paper", "--scene", "free-space-x", "--json",
                                  "--fidelity", "draft", *extra])
        assert res.exit_code == 0, res.output
        out = json.loads(res.stdout)["metrics"]
        return out["paper_metric"], out["controller_period_ms"]

    hi, T_hi = residual("--force-gain", "400", "--period-ms", "0.5")
    lo, T_lo = residual("--force-gain", "45", "--period-ms", "0.5")
    assert T_hi == T_lo == 0.5 and hi < lo


def test_a_verdict_other_than_ok_exits_3():
    # seed 000 eq 18–19: the stable wall stiffness falls as 1/T (2.67 N/mm at T = 1 ms, the handle's
    # stability evaluator); at T = 10 ms the scene's K_e = 2 N/mm is far above it: unstable, exit 3
    res = runner.invoke(app, ["verify", "--preset", "handle-paper", "--scene", "handle-wall", "--period-ms", "10",
                              "--json"])
    assert res.exit_code == 3, res.output
    assert json.loads(res.stdout)["status"] == "unstable"
    assert res.stderr.startswith("not met: verify handle-wall: unstable")


def test_verify_lists_the_values_the_paper_does_not_give():
    """Issue 30: free-space-x at the paper's K_p = 45 beside its 0.50 N, with every assumed value (key, the
    value this run used, its source) in the JSON and as `assumed:` lines in the text output."""
    res = runner.invoke(app, ["verify", "--preset", "prrr-paper", "--scene", "free-space-x", "--json",
                              "--fidelity", "draft", "--period-ms", "0.5"])
    assert res.exit_code == 0, res.output
    m = json.loads(res.stdout)["metrics"]
    assert m["paper_value"] == 0.50 and m["paper_metric"] > 0
    got = {a["key"]: a["value"] for a in m["assumptions"]}
    assert got["controller.period_ms"] == 0.5 and got["controller.force_gain"] == 45.0  # the override shows
    assert got["design.structure.joint_friction_Nm"] == pytest.approx(0.0384)
    assert all(a["source"] for a in m["assumptions"])
    text = runner.invoke(app, ["verify", "--preset", "prrr-paper", "--scene", "free-space-x", "--fidelity", "draft"])
    assert text.exit_code == 0 and "assumed: controller.period_ms = 1" in text.output.replace("\n", " ")
