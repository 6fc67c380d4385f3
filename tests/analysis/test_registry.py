"""``analysis.registry``: every metric an evaluator reports is described in its entry (the glossary's
one source), at the fidelity levels the entry names; units come from the name's suffix."""

from __future__ import annotations

import pytest

from hapticopt.analysis import registry
from hapticopt.analysis.compute import Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design import io
from hapticopt.design.errors import InvalidInput

PRESETS = {"prrr": "prrr-paper", "master": "master-paper", "handle": "handle-paper"}


@pytest.mark.parametrize("level", [Fidelity.DRAFT, Fidelity.STANDARD])
@pytest.mark.parametrize("device", sorted(PRESETS))
def test_entries_describe_exactly_the_reported_metrics(device: str, level: Fidelity):
    """Fine (the 3-PRRR's solid FEA takes a minute) was checked the same way when the descriptions
    were written: its extra metrics are the entries marked fine-only."""
    every = tuple(e.name for e in registry.EVALUATORS[device])  # on-request evaluators included
    ev = registry.evaluate_all(io.load_preset(PRESETS[device]), fidelity=level, only=every)
    for entry in registry.EVALUATORS[device]:
        assert ev.statuses[entry.name] == "ok", (entry.name, ev.messages[entry.name])
        reported = set(ev.results[entry.name].metrics())
        described = {m.name for m in entry.metrics if level in m.fidelities}
        assert reported == described, (entry.name, reported ^ described)


def test_every_entry_has_descriptions_and_a_fidelity_note():
    for device, entries in registry.EVALUATORS.items():
        names = [m.name for e in entries for m in e.metrics]
        assert len(names) == len(set(names)), device  # one meaning per name and device
        for e in entries:
            assert e.fidelity and e.metrics, (device, e.name)
            for m in e.metrics:
                assert m.description and m.fidelities, m.name


@pytest.mark.parametrize(("name", "unit"), [
    ("stiffness_limit_N_per_mm", "N/mm"), ("max_force_N", "N"), ("force_loop_bandwidth_Hz", "Hz"),
    ("device_mass_kg", "kg"), ("joint_elbow_limit_deg", "deg"), ("workspace_volume_mm3", "mm³"),
    ("pade_minus_exact_pct", "%"), ("sweep_wall_damping_Ns_per_m", "N·s/m"),
    ("structural_fea_max_von_mises_MPa_per_N", "MPa/N"),  # not "N": the whole "A_per_B" suffix
    ("stiffness_limit_N_per_mm[2]", "N/mm"), ("jacobian_condition", ""), ("workspace_coverage", ""),
    ("jacobian_condition_min", ""),  # "min" is not a unit
    ("growth_rate_per_s", "1/s"),  # a rate, not a time
])
def test_metric_unit_from_the_suffix(name: str, unit: str):
    assert registry.metric_unit(name) == unit


def test_glossary_rows_and_bad_device():
    rows = registry.glossary("master")
    assert {r["device"] for r in rows} == {"master"}
    worst = next(r for r in rows if r["metric"] == "transparency_bandwidth_worst_Hz")
    assert worst["fidelities"] == ["standard", "fine"] and worst["unit"] == "Hz"
    assert len(registry.glossary()) == sum(len(registry.glossary(d)) for d in registry.EVALUATORS)
    with pytest.raises(InvalidInput, match=r"--device = 'robot' is not a device: allowed prrr, master, handle"):
        registry.glossary("robot")


def test_run_plotter_returns_the_files_it_wrote_for_a_relative_folder(monkeypatch, tmp_path):
    """A plotter returns ``out_dir / name`` as it wrote it; with a relative ``out_dir`` that path is
    relative to the working folder, and run_plotter must return it as such (it once read it as
    relative to ``out_dir``: the report's pictures then pointed at plots/<out_dir>/plots/…)."""
    from pathlib import Path

    def plotter(design, result, out_dir):
        target = Path(out_dir) / f"{design.name}_x.png"
        target.write_bytes(b"png")
        return [target]

    def outside(design, result, out_dir):
        return [Path(out_dir) / ".." / "escaped.png"]

    monkeypatch.chdir(tmp_path)
    (tmp_path / "run" / "plots").mkdir(parents=True)
    design = io.load_preset("prrr-paper")
    entry = registry.EVALUATORS["prrr"][0]
    monkeypatch.setattr(registry.EvaluatorEntry, "plotter", lambda self: plotter)
    files = registry.run_plotter(entry, design, None, Path("run/plots"))
    assert files == [Path("run/plots/prrr-paper_x.png")] and all(f.is_file() for f in files)
    monkeypatch.setattr(registry.EvaluatorEntry, "plotter", lambda self: outside)
    with pytest.raises(InvalidInput, match="outside the output folder"):
        registry.run_plotter(entry, design, None, Path("run/plots"))


def test_compute_goes_only_to_the_entries_that_take_it(monkeypatch):
    """``compute=`` reaches exactly the evaluators whose entry says ``takes_compute`` (the same object the
    caller passed), ``shared=`` those that say ``shared``; the others get neither keyword."""
    seen: dict[str, set[str]] = {}
    got: list[object] = []

    def load(entry):
        def evaluate(design, *, fidelity, **kw):
            seen[entry.name] = set(kw)
            got.extend(v for k, v in kw.items() if k == "compute")
            raise RuntimeError("probe")  # a failed status: the loop goes on

        return type("Probe", (), {"evaluate": staticmethod(evaluate)})

    monkeypatch.setattr(registry.EvaluatorEntry, "load", load)
    route = Compute(backend="numpy", threads=1)
    ev = registry.evaluate_all(io.load_preset("prrr-paper"), fidelity=Fidelity.STANDARD, compute=route)
    for entry in registry.EVALUATORS["prrr"]:
        expected = {k for k, on in (("shared", entry.shared), ("compute", entry.takes_compute)) if on}
        assert seen[entry.name] == expected, entry.name
        assert ev.statuses[entry.name] == "failed"
    assert got and all(c is route for c in got)
    assert {e.name for e in registry.EVALUATORS["prrr"] if e.takes_compute} == {
        "structural_stiffness", "interference", "free_workspace", "strength"}


def test_batch_entries_name_functions_that_exist():
    """Every batch evaluator and single-path check a :data:`registry.BATCHED` entry names can be loaded."""
    for device, batch in registry.BATCHED.items():
        assert device in registry.EVALUATORS
        assert callable(registry._function(batch.evaluate_many)) and callable(registry._function(batch.single_path))
        assert batch.chunk >= 1


def test_evaluate_batch_of_other_levels_or_devices_is_evaluate_all_of_each(monkeypatch):
    """A list at a level no batch evaluator serves, or of a device without one, takes evaluate_all per
    design with the caller's Compute."""
    calls = []
    monkeypatch.setattr(registry, "evaluate_all", lambda d, **kw: calls.append((d.name, kw["compute"])) or d.name)
    route = Compute(threads=1)
    prrr, master = io.load_preset("prrr-paper"), io.load_preset("master-paper")
    assert registry.evaluate_batch([prrr, prrr], fidelity=Fidelity.STANDARD, compute=route) == [prrr.name] * 2
    assert registry.evaluate_batch([master], fidelity=Fidelity.DRAFT, compute=route) == [master.name]
    assert registry.evaluate_batch([], fidelity=Fidelity.DRAFT) == []
    assert calls == [(prrr.name, route)] * 2 + [(master.name, route)]


def test_every_registered_metric_declares_its_direction():
    """issue 33: compare and the reports colour a change by better/worse; a metric without a direction
    would silently be neutral."""
    missing = sorted({m.name for entries in registry.EVALUATORS.values() for e in entries for m in e.metrics}
                     - set(registry.DIRECTIONS))
    assert not missing, ("metrics without a direction: add each to DIRECTIONS in analysis/registry.py as "
                         "_H (higher is better), _L (lower is better) or _0 (neutral): " + ", ".join(missing))


@pytest.mark.parametrize(("name", "ref", "value", "verdict"), [
    ("device_mass_kg", 4.4, 4.6, "worse"),  # heavier
    ("device_mass_kg", 4.4, 4.2, "better"),
    ("jacobian_condition", 2.449, 2.6, "worse"),
    ("stiffness_limit_N_per_mm[1]", 40.0, 45.0, "better"),  # a component: the vector's direction
    ("elastic_centre_mm", 10.0, 12.0, "changed"),  # neutral
    ("not_a_registered_metric", 1.0, 2.0, "changed"),  # unknown: neutral at run time
    ("jacobian_condition", 2.449, 2.449 * (1 + 2.8e-15), "same"),  # rounding (issue 33: +2.8e-13 % was coloured)
    ("jacobian_condition", 0.0, 0.0, "same"),
    ("jacobian_condition", float("nan"), 1.0, ""),
])
def test_judge_by_direction_and_tolerance(name, ref, value, verdict):
    assert registry.judge(name, ref, value) == verdict


def test_an_on_request_evaluator_runs_at_that_fidelity_only_when_named():
    """The strength check runs at draft only when asked for (``only``), in the single path and the batch
    alike; at standard it is part of every evaluation (registry.EvaluatorEntry.on_request_at)."""
    from hapticopt.analysis.registry import evaluate_all, evaluate_batch
    from hapticopt.design import io

    d = io.load_preset("prrr-paper")
    assert "strength" not in evaluate_all(d, fidelity=Fidelity.DRAFT).results
    assert "strength" not in evaluate_batch([d, d], fidelity=Fidelity.DRAFT)[1].results
    asked = evaluate_all(d, fidelity=Fidelity.DRAFT, only=("strength",))
    batch = evaluate_batch([d], fidelity=Fidelity.DRAFT, only=("statics", "strength"))[0]
    assert asked.statuses["strength"] == batch.statuses["strength"] == "ok"
    assert asked.metrics()["safety_factor_yield"] == batch.metrics()["safety_factor_yield"] > 0
    assert "strength" in evaluate_all(d, fidelity=Fidelity.STANDARD, only=None).results
