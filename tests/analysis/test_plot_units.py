"""Every plotter the registry names (``"module:function"``) labels each axis it draws with a unit.

The pictures are drawn for real (each device's bundled preset at draft fidelity); the test reads
the labels from the objects before they are saved: matplotlib Axes (every axis whose tick labels
are shown, colour bars included) and pyvista's bounding-box axes and scalar-bar titles.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.registry import EVALUATORS, evaluate_all, run_plotter
from hapticopt.design import io

#: a unit in brackets ("[mm]", "[-]", "[N/mm]") or, as VTK renders brackets, in parentheses
UNIT = re.compile(r"\[[^\]]+\]|\([^)]*\)")
PRESETS = {"prrr": "prrr-paper", "master": "master-paper", "handle": "handle-paper"}


@pytest.fixture
def drawn(monkeypatch):
    """Labels of every figure saved while the fixture is active: a list of (figure kind, axis, label)."""
    import matplotlib
    import pyvista as pv

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    seen: list[tuple[str, str, str]] = []
    save = Figure.savefig

    def savefig(fig, *args, **kwargs):
        fig.canvas.draw()
        for ax in fig.axes:
            for name, axis, label in (("x", ax.xaxis, ax.get_xlabel()), ("y", ax.yaxis, ax.get_ylabel())):
                shown = axis.get_visible() and any(t.get_visible() and t.get_text() for t in axis.get_ticklabels())
                if shown:
                    seen.append(("matplotlib", name, label))
        return save(fig, *args, **kwargs)

    shot = pv.Plotter.screenshot

    def screenshot(pl, *args, **kwargs):
        actor = pl.renderer.cube_axes_actor
        if actor is not None:
            seen.extend([("pyvista", "x", actor.GetXTitle()), ("pyvista", "y", actor.GetYTitle()),
                         ("pyvista", "z", actor.GetZTitle())])
        seen.extend(("pyvista", "colour bar", title) for title in pl.scalar_bars.keys())
        return shot(pl, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    monkeypatch.setattr(pv.Plotter, "screenshot", screenshot)
    return seen


@pytest.mark.parametrize("device", sorted(EVALUATORS))
def test_every_registry_plotter_labels_its_axes_with_units(device, drawn, tmp_path):
    entries = [e for e in EVALUATORS[device] if e.plot is not None]
    assert entries, f"no plotter registered for {device}"
    design = io.load_preset(PRESETS[device])
    ev = evaluate_all(design, fidelity=Fidelity.DRAFT, only=tuple(e.name for e in entries))
    for entry in entries:
        before = len(drawn)
        files = run_plotter(entry, design, ev.results[entry.name], tmp_path)
        assert files and all(f.is_file() for f in files), entry.plot
        labels = drawn[before:]
        assert labels, f"{entry.plot}: no labelled axis seen"
        missing = [(kind, axis, label) for kind, axis, label in labels if not UNIT.search(label or "")]
        assert not missing, f"{entry.plot}: axes without a unit: {missing}"


def test_counterweight_trade_off_puts_hertz_and_newtons_on_twin_axes(drawn, tmp_path):
    from hapticopt.analysis.master.plots import sweep_plot

    rows = [{"counterweight_mass_kg": m, "transparency_bandwidth_x_Hz": 10 - m, "transparency_bandwidth_z_Hz": 9 - m,
             "max_unbalance_force_N": abs(0.5 - m), "com_offset_mm": 1.0, "unbalance_radius_mm": 2.0}
            for m in np.linspace(0.1, 1.0, 5)]
    sweep_plot(rows, tmp_path / "sweep.png", boundary_mass=0.5)
    ys = [label for kind, axis, label in drawn if axis == "y"]
    assert ys == ["transparency bandwidth [Hz]", "max unbalance force [N]"]
    assert [label for kind, axis, label in drawn if axis == "x"] == ["total counterweight mass [g]"]


def test_the_check_sees_a_missing_unit(drawn, tmp_path):
    """The fixture reads real labels: a plot without a unit is caught."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([1, 2], [3, 4])
    ax.set_xlabel("value")
    fig.savefig(tmp_path / "bad.png")
    plt.close(fig)
    assert ("matplotlib", "x", "value") in drawn and ("matplotlib", "y", "") in drawn
    assert not UNIT.search("value")
