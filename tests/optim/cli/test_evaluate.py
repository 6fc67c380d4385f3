"""``hapticopt evaluate`` / ``presets``: output, JSON schema, and one-line errors with exit code 2."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hapticopt.optim.cli import app

runner = CliRunner()


def invoke(*args: str):
    return runner.invoke(app, list(args))


def test_evaluate_preset_json_has_reference_metrics():
    res = invoke("evaluate", "--preset", "prrr-paper", "--json")
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert set(out) >= {"design", "metrics", "timings_s"}
    m = out["metrics"]
    # seed 002 Table 1 and eq 15 (see tests/analysis/prrr/structure/test_statics.py for the sources)
    assert m["max_force_N"] == pytest.approx([1378, 1194, 3581], rel=2e-3)
    assert m["stiffness_limit_N_per_mm"] == pytest.approx([28.14, 28.14, 168.8], rel=2e-3)
    assert m["jacobian_condition"] == pytest.approx(6**0.5, rel=1e-12)
    assert len(m["effective_mass_kg"]) == 3
    assert out["design"]["geometry"]["beta_deg"] == 60.0


def test_set_changes_design():
    res = invoke("evaluate", "--preset", "prrr-paper", "--set", "geometry.beta_deg=35.26", "--json")
    # at the isotropic β the φ140 mm cylinder no longer fits (reach radius 52.3 mm): exit 3, JSON intact
    assert res.exit_code == 3, res.output
    assert json.loads(res.stdout)["metrics"]["jacobian_condition"] == pytest.approx(1.0, abs=1e-3)
    assert res.stderr.startswith("not met: ") and "workspace (not-met)" in res.stderr


def test_a_design_that_cannot_be_assembled_exits_3_and_says_so():
    # issue 21: prrr-paper with d2 = 300 mm exited 0 with "statics: ok" (tests/analysis/prrr/geometry/test_assembly.py
    # derives why no pose closes the chain)
    res = invoke("evaluate", "--preset", "prrr-paper", "--set", "geometry.d2_mm=300", "--fidelity", "draft", "--json")
    assert res.exit_code == 3, res.output
    out = json.loads(res.stdout)
    assert set(out["status"].values()) == {"not-assemblable"}
    assert "does not close" in out["messages"]["statics"]
    assert out["metrics"]["jacobian_condition"] is None  # no plausible-looking number: JSON null, named in null_numbers
    assert out["null_numbers"]["/metrics/jacobian_condition"] == "NaN"
    assert len(res.stderr.strip().splitlines()) == 1 and "statics (not-assemblable)" in res.stderr


def test_a_design_whose_parts_cannot_be_laid_out_has_no_ok_metric():
    # issue 30 item 2: Table 2's r_p = 100 mm with prrr-paper's rail angle θ_1p = 83° — no face of the carriage
    # block carries the R1 clevis (design.prrr.layout) — printed footprint 260 mm and k_x 43.3 N/mm with "ok"
    res = invoke("evaluate", "--preset", "prrr-paper", "--set", "geometry.r_p_mm=100", "--set", "geometry.theta_1p_deg=83",
                 "--fidelity", "draft", "--json")
    assert res.exit_code == 3, res.output
    out = json.loads(res.stdout)
    assert set(out["status"].values()) == {"not-assemblable"}
    assert all("the parts cannot be laid out" in m for m in out["messages"].values())
    assert all(v is None or (isinstance(v, float) and math.isnan(v)) for v in out["metrics"].values())


def test_a_missed_workspace_requirement_is_not_met_in_the_table():
    # issue 21: "workspace: ok — a cylinder of diameter 140 mm does not fit"
    res = invoke("evaluate", "--preset", "prrr-paper", "--set", "geometry.d3_mm=60", "--set", "geometry.d4_mm=60",
                 "--fidelity", "draft")
    assert res.exit_code == 3
    assert "workspace: not-met — the required φ140 × 89 mm cylinder does not fit" in res.stdout
    assert "workspace: ok" not in res.stdout


def test_table_output_names_metrics_with_units():
    res = invoke("evaluate", "--preset", "prrr-paper")
    assert res.exit_code == 0
    for name in ("jacobian_condition", "max_force_N", "stiffness_limit_N_per_mm", "effective_mass_kg"):
        assert name in res.stdout


def test_evaluate_design_file(tmp_path: Path):
    from hapticopt.design import io

    path = tmp_path / "mine.toml"
    io.save_design(io.apply_overrides(io.load_preset("prrr-paper"), ["name=mine"]), path)
    res = invoke("evaluate", str(path), "--json")
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["design"]["name"] == "mine"


def test_presets_lists_both_devices():
    res = invoke("presets")
    assert res.exit_code == 0
    assert "prrr-paper" in res.stdout and "master-paper" in res.stdout


@pytest.mark.parametrize(
    ("args", "pattern"),
    [
        (("--preset", "prrr-paper", "--set", "geometry.beta_deg=0"), "geometry.beta_deg = 0 is out of range: allowed 0 < beta_deg < 90 (deg)"),
        (("--preset", "prrr-paper", "--set", "geometry.beta_deg=90"), "geometry.beta_deg = 90 is out of range"),
        (("--preset", "prrr-paper", "--set", "geometry.d3_mm=-5"), "geometry.d3_mm = -5 is out of range: allowed 0 < d3_mm ≤ 2000 (mm)"),
        (("--preset", "prrr-paper", "--set", "geometry.d3_mm=0"), "geometry.d3_mm = 0 is out of range"),
        (("--preset", "prrr-paper", "--set", "geometry.zz_mm=1"), "geometry.zz_mm is not a known parameter"),
        (("--preset", "prrr-paper", "--set", "geometry.beta_deg=abc"), "geometry.beta_deg = 'abc' is not a number"),
        (("--preset", "nope"), "preset 'nope' does not exist"),
        (("/definitely/missing.toml",), "does not exist"),
        (("--preset", "prrr-paper", "--fidelity", "ultra"), "--fidelity = 'ultra' is not a fidelity level"),
        ((), "give exactly one of FILE or --preset"),
    ],
)
def test_bad_input_is_one_line_exit_2(args, pattern):
    res = invoke("evaluate", *args)
    assert res.exit_code == 2
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, res.stderr
    assert pattern in lines[0]
    assert "Traceback" not in res.output


def test_malformed_and_unknown_key_files(tmp_path: Path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[geometry\n")
    res = invoke("evaluate", str(bad))
    assert res.exit_code == 2 and "is not valid TOML" in res.stderr
    unknown = tmp_path / "unknown.toml"
    unknown.write_text('name = "u"\ndevice = "prrr"\nfoo = 1\n')
    res = invoke("evaluate", str(unknown))
    assert res.exit_code == 2 and "foo is not a known key" in res.stderr


def test_console_script_end_to_end_no_traceback():
    """The installed entry point: real process, one error line, exit 2."""
    exe = Path(sys.executable).with_name("hapticopt")
    res = subprocess.run([str(exe), "evaluate", "--preset", "prrr-paper", "--set", "geometry.beta_deg=95"],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 2
    assert res.stderr.strip().count("\n") == 0 and "geometry.beta_deg = 95" in res.stderr
    ok = subprocess.run([str(exe), "evaluate", "--preset", "prrr-paper", "--json"],
                        capture_output=True, text=True, timeout=120)
    assert ok.returncode == 0 and json.loads(ok.stdout)["metrics"]["jacobian_condition"] > 2.4


def test_help_is_accurate():
    res = invoke("--help")
    assert res.exit_code == 0
    for cmd in ("evaluate", "presets"):
        assert cmd in res.stdout
    res = invoke("evaluate", "--help")
    for opt in ("--preset", "--set", "--fidelity", "--json", "--plots"):
        assert opt in res.stdout


def test_evaluate_handle_preset():
    # seed 000's handle as a third device: eq (19) with the paper's B_e (2.67 N/mm ± 1 %) through the registry
    res = invoke("evaluate", "--preset", "handle-paper", "--json")
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["status"] == {"stability": "ok", "upsampling": "ok", "zwidth": "ok"}
    assert out["metrics"]["max_stable_stiffness_N_per_mm"] == pytest.approx(2.67, rel=0.01)
    assert out["design"]["drive"]["motor_inertia_g_cm2"] == 34.7


def test_evaluate_handle_bad_value_exit_2():
    res = invoke("evaluate", "--preset", "handle-paper", "--set", "firmware.period_ms=0")
    assert res.exit_code == 2
    assert res.output.strip().splitlines()[-1].endswith("firmware.period_ms = 0 is out of range: allowed 0 < period_ms ≤ 100 (ms)")
