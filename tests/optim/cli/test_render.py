"""``optim.cli.render``: numbers with units and sensible digits, arrays summarised, no Python reprs,
tables that wrap instead of cutting."""

from __future__ import annotations

import io
import math

import pytest
from rich.console import Console

from hapticopt.optim.cli import render


@pytest.mark.parametrize(("x", "text"), [
    (31.673930686807186, "31.67"), (2207380.5, "2.207e6"), (2.034e-16, "2.034e-16"), (140.0, "140"),
    (0.0, "0"), (-16.7756, "-16.78"), (3000, "3000"), (math.nan, "—"), (math.inf, "inf"), (True, "yes"),
])
def test_number(x, text):
    assert render.number(x) == text


@pytest.mark.parametrize(("name", "v", "text"), [
    ("max_force_N", [1378.33, 1193.67, 3581.0], "[1378, 1194, 3581] N"),
    ("stiffness_error_pct", 0.1708, "0.1708%"),
    ("wall_penetration_mm", None, "—"),
    ("stable", True, "yes"),
    ("effects", ["gravity", "sampling"], "gravity, sampling"),
    ("effective_mass_kg", [[1.0, 0.5], [0.5, 1.0]], "[[1, 0.5], [0.5, 1]] kg"),
    ("backend", "lumped", "lumped"),
    ("rendered_damping_Ns_per_m", 381.5676, "381.6 N·s/m"),
])
def test_metric_values(name, v, text):
    assert render.metric(name, v) == text


def test_long_arrays_are_summarised_with_undefined_counted():
    values = [float(k) for k in range(20)] + [None, math.nan]
    assert render.metric("zwidth_boundary_N_per_mm", values) == "22 values: min 0, max 19 N/mm (2 undefined)"


def test_no_python_reprs_in_a_metrics_table():
    metrics = {"stable": True, "unstable_at_s": None, "residual_force_rms_N": 31.673930686807186,
               "notes": [], "structural_stiffness_at_elastic_centre_N_per_mm": [58.0558, 58.0558, 241.377]}
    buf = io.StringIO()
    Console(file=buf, width=80).print(render.metrics_table("t", metrics))
    text = buf.getvalue()
    for repr_ in ("None", "True", "False", "31.673930686807186", "[]"):
        assert repr_ not in text
    # the long name wraps onto the next line: its pieces in the first column give it back whole
    assert "…" not in text
    first_column = "".join(ln.split("│")[1].strip() for ln in text.splitlines() if ln.startswith("│"))
    assert "structural_stiffness_at_elastic_centre_N_per_mm" in first_column
    assert max(len(ln) for ln in text.splitlines()) <= 80


def test_number_tables_fit_the_width_and_repeat_the_key_column():
    cols = ["counterweight_fraction", *(f"quantity_number_{k}_N_per_mm" for k in range(8))]
    rows = [[render.number(0.05 * i), *(render.number(1234.5678 * i + k) for k in range(8))] for i in range(5)]
    tables = render.number_tables("sweep", cols, rows, width=80)
    assert len(tables) > 1
    for t in tables:
        buf = io.StringIO()
        Console(file=buf, width=80).print(t)
        lines = buf.getvalue().splitlines()
        assert all(len(ln) <= 80 for ln in lines)
        assert "…" not in buf.getvalue()
        assert t.columns[0].header == "counterweight_fraction"
    shown = [c.header for t in tables for c in t.columns[1:]]
    assert shown == cols[1:]
