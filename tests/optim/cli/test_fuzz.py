"""Fuzzed design, scene and problem files and ``--set`` (issue 14, item 6).

Each example takes a bundled file, puts a hostile value (or key) at one place, and runs the real
CLI in-process. The expensive work behind a valid input (evaluators, simulation, the pipeline)
is replaced by a stub that only records it was reached: the code under test is every check in
front of it. Asserted per example: exit code 0 (stub reached) or 2; on 2, exactly one stderr
line, no traceback, naming the field (or the file, for text that is not TOML); nothing written
anywhere in the working folder. 4 × 250 examples, derandomised (tests/conftest.py profile),
~20–40 s on this machine.
"""

from __future__ import annotations

import tempfile
import tomllib
from importlib import resources
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from hapticopt.optim.cli import app

N_EXAMPLES = 250  # per kind: 1000 generated inputs in all (issue 14 asks for ≥ 1000)

HOSTILE = [
    "1" + "0" * 400,  # OverflowError on float() in the issue
    "9" * 5000,  # past Python's int-conversion limit: tomllib raised ValueError
    "[" * 2000 + "]" * 2000,  # RecursionError in tomllib
    "{ a = 1 }", "[1, 2]", "[[1], [2]]", '{ x = [1, { y = 2 }] }',
    '"../x"', '"/abs/evil"', '"a\\u0000b"', '"\\u001b[31mred"', '"' + "x" * 100_000 + '"', '""', '"  "',
    "5e-324", "1e308", "-1e308", "inf", "-inf", "nan", "-1", "0", "0.0", "true", "false",
    "9223372036854775807", "9223372036854775808", "-9223372036854775809", "2147483648", "0x7fffffff",
    "[" + ", ".join(["1.5"] * 20_000) + "]",
    "1979-05-27T07:32:00Z", "07:32:00", '"60 deg"', '"draft"', '"no-such-scene"', '["no-such-scene"]',
]
GARBAGE_LINES = ["= 1", "[[[x]]]", "a = 1\na = 2", "key = ", '"unterminated', "[table\n", "\x00 = 1"]


def _bundled(package: str, name: str) -> dict:
    return tomllib.loads((resources.files(package) / f"{name}.toml").read_text())


def _raw(value) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, list):
        return "[" + ", ".join(_raw(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_raw(v)}" for k, v in value.items()) + " }"
    raise TypeError(value)


class Raw(str):
    """A value already in TOML syntax (the hostile text)."""


def _dump(doc: dict) -> str:
    def val(v):
        return str(v) if isinstance(v, Raw) else _raw(v)

    lines = [f"{k} = {val(v)}" for k, v in doc.items()
             if not isinstance(v, dict) and not (isinstance(v, list) and v and isinstance(v[0], dict))]
    for k, v in doc.items():
        if isinstance(v, dict):
            lines += ["", f"[{k}]"] + [f"{kk} = {val(vv)}" for kk, vv in v.items()]
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                lines += ["", f"[[{k}]]"] + [f"{kk} = {val(vv)}" for kk, vv in item.items()]
    return "\n".join(lines) + "\n"


def _places(doc: dict) -> list[tuple]:
    """Every (container path, key) where a value can be replaced or a key added."""
    out = []
    for k, v in doc.items():
        if isinstance(v, dict):
            out += [((k,), kk) for kk in v] + [((k,), "zz_unknown")]
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for i, item in enumerate(v):
                out += [((k, i), kk) for kk in item] + [((k, i), "zz_unknown")]
        else:
            out.append(((), k))
    return out + [((), "zz_unknown")]


def _mutate(doc: dict, place: tuple, value: str, delete: bool) -> tuple[dict, str]:
    import copy

    doc = copy.deepcopy(doc)
    path, key = place
    target = doc
    for p in path:
        target = target[p]
    if delete and key in target:
        del target[key]
    else:
        target[key] = Raw(value)
    return doc, key


def _mutations(doc: dict):
    return st.tuples(st.sampled_from(_places(doc)), st.sampled_from(HOSTILE), st.booleans(),
                     st.sampled_from([None] * 30 + GARBAGE_LINES))


class Reached(BaseException):  # not an Exception: it passes the CLI boundary
    pass


@pytest.fixture
def stubs(monkeypatch):
    """Stand-ins for the expensive work behind a valid input (they only say they were reached)."""
    from hapticopt.optim import pipeline
    from hapticopt.optim.cli import evaluate as cli_evaluate
    from hapticopt.analysis import verify as closed_loop_verify  # the CLI imports it when `verify` runs

    def reached(*args, **kwargs):
        raise Reached

    monkeypatch.setattr(cli_evaluate, "evaluate_all", reached)
    monkeypatch.setattr(closed_loop_verify, "simulate", reached)
    monkeypatch.setattr(pipeline, "run_pipeline", reached)


def _check(args: list[str], work: Path, inputs: set[Path], key: str | None, source: str) -> None:
    try:
        res = CliRunner().invoke(app, args)
    except Reached:  # a valid input reached the (stubbed) work
        res = None
    if res is not None:
        assert res.exit_code == 2, (args[:3], res.output[-500:], repr(res.exception))
        assert "Traceback" not in res.output
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr[-500:]
        line = lines[0]
        assert len(line) <= 1000
        assert (key is not None and key in line) or "TOML" in line or source in line or "--set" in line, line
    written = {p for p in work.rglob("*")} - inputs
    assert not written, sorted(map(str, written))[:5]


SETTINGS = settings(max_examples=N_EXAMPLES, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                           HealthCheck.data_too_large])


def _run_file(kind_doc: dict, mutation, args_of, name: str, monkeypatch) -> None:
    place, value, delete, garbage = mutation
    doc, key = _mutate(kind_doc, place, value, delete)
    text = _dump(doc) + ("" if garbage is None else "\n" + garbage + "\n")
    with tempfile.TemporaryDirectory() as d:
        work = Path(d)
        monkeypatch.chdir(work)
        f = work / name
        f.write_text(text, encoding="utf-8")
        _check(args_of(f), work, {f}, key, name)


DESIGN = _bundled("hapticopt.design.presets", "prrr-paper")
SCENE = _bundled("hapticopt.analysis.scenes", "stiffness-25")
PROBLEM = _bundled("hapticopt.optim.problems", "prrr-workspace")


@SETTINGS
@given(mutation=_mutations(DESIGN))
def test_fuzz_design_files(stubs, monkeypatch, mutation):
    _run_file(DESIGN, mutation, lambda f: ["evaluate", str(f)], "design.toml", monkeypatch)


@SETTINGS
@given(mutation=_mutations(SCENE))
def test_fuzz_scene_files(stubs, monkeypatch, mutation):
    _run_file(SCENE, mutation, lambda f: ["verify", "--preset", "prrr-paper", "--scene", str(f)], "scene.toml",
              monkeypatch)


@SETTINGS
@given(mutation=_mutations(PROBLEM))
def test_fuzz_problem_files(stubs, monkeypatch, mutation):
    _run_file(PROBLEM, mutation, lambda f: ["optimise", str(f), "--quiet"], "problem.toml", monkeypatch)


SET_KEYS = ["name", "description", "geometry.beta_deg", "actuator.spring_N_per_mm", "structure.bore_diameter_mm",
            "geometry", "geometry.", ".x", "nosection.x", "geometry.nokey", "a.b.c", ""]


@SETTINGS
@given(key=st.sampled_from(SET_KEYS), value=st.sampled_from(HOSTILE + ["60", "45.5", "abc", "[", "=", "a=b"]),
       no_equals=st.booleans())
def test_fuzz_set(stubs, monkeypatch, key, value, no_equals):
    with tempfile.TemporaryDirectory() as d:
        work = Path(d)
        monkeypatch.chdir(work)
        assignment = key if no_equals else f"{key}={value}"
        _check(["evaluate", "--preset", "prrr-paper", "--set", assignment], work, set(), key.split(".")[-1] or None,
               "--set")


@pytest.mark.parametrize("scenes", ['["a\\u0000b"]', '["' + "s" * 5000 + '"]', '["' + "/x" * 300 + '.toml"]'])
def test_problem_scene_names_that_are_not_paths(stubs, tmp_path, monkeypatch, scenes):
    monkeypatch.chdir(tmp_path)
    doc, _ = _mutate(PROBLEM, (("verify",), "scenes"), scenes, False)
    f = tmp_path / "p.toml"
    f.write_text(_dump(doc))
    _check(["optimise", str(f), "--quiet"], tmp_path, {f}, "scenes", "p.toml")
