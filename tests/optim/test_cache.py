"""The evaluation cache (optim/cache.py): key, reuse to the bit, faults, two processes, a killed writer."""

from __future__ import annotations

import contextlib
import hashlib
import dataclasses
import json
import math
import os
import signal
import sqlite3
import struct
import subprocess
import sys

import pytest

from hapticopt.design.errors import InputFileError

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design import io
from hapticopt.optim import cache as C
from hapticopt.optim.cache import EvaluationCache, cache_key, canonical


@pytest.fixture(scope="module")
def handle():
    return io.load_preset("handle-paper")


def bits(value):
    """A value with every float replaced by its IEEE-754 bit pattern (NaN kept as the string 'nan':
    JSON keeps NaN, not its sign bit or payload)."""
    if isinstance(value, float):
        return "nan" if math.isnan(value) else struct.pack("<d", value).hex()
    if isinstance(value, list):
        return [bits(v) for v in value]
    if isinstance(value, dict):
        return {k: bits(v) for k, v in value.items()}
    return value


# ------------------------------------------------------------------------------------ the key
def test_key_changes_with_design_fidelity_evaluators_and_code(handle):
    k = cache_key(handle, Fidelity.DRAFT, None, code="v1")
    assert cache_key(handle, Fidelity.DRAFT, None, code="v1") == k
    assert cache_key(io.load_preset("handle-paper"), Fidelity.DRAFT, None, code="v1") == k  # an equal design
    assert cache_key(handle, Fidelity.STANDARD, None, code="v1") != k
    assert cache_key(handle, Fidelity.DRAFT, ("stability",), code="v1") != k
    assert cache_key(handle, Fidelity.DRAFT, None, code="v2") != k
    section = handle.SECTIONS[0]
    sec = getattr(handle, section)
    name, value = next((f.name, getattr(sec, f.name)) for f in dataclasses.fields(sec)
                       if isinstance(getattr(sec, f.name), float))
    nudged = dataclasses.replace(handle, **{section: dataclasses.replace(sec, **{name: math.nextafter(value, math.inf)})})
    assert cache_key(nudged, Fidelity.DRAFT, None, code="v1") != k  # one ulp of one field is another design
    assert cache_key(dataclasses.replace(handle, name="other"), Fidelity.DRAFT, None, code="v1") != k


def test_canonical_keeps_float_bits_and_refuses_unknown_types():
    assert canonical(0.1) == ["float", (0.1).hex()]
    assert canonical(-0.0) != canonical(0.0)
    assert canonical((1, 1.0)) != canonical((1.0, 1))
    with pytest.raises(TypeError, match="cannot key a object"):
        canonical(object())


def test_code_version_follows_the_source(tmp_path, monkeypatch):
    """An edit to any evaluator source file changes the code version (a scratch copy of a package)."""
    import hapticopt.analysis as analysis

    first = C.code_version()
    assert first == C.code_version() and len(first) == 64
    scratch = tmp_path / "analysis"
    scratch.mkdir()
    (scratch / "evaluator.py").write_text("K = 1.0\n")
    monkeypatch.setattr(analysis, "__path__", [str(scratch)])
    C.code_version.cache_clear()
    try:
        one = C.code_version()
        (scratch / "evaluator.py").write_text("K = 1.0000001\n")
        C.code_version.cache_clear()
        assert C.code_version() != one
    finally:
        C.code_version.cache_clear()


# ------------------------------------------------------------------------------ hit, miss, bits
def test_second_evaluation_is_served_from_the_cache_bit_for_bit(tmp_path, handle):
    with EvaluationCache(tmp_path / "c.sqlite") as cache:
        first = C.evaluate(handle, Fidelity.DRAFT, cache=cache)
        again = C.evaluate(handle, Fidelity.DRAFT, cache=cache)
        assert (cache.misses, cache.hits, cache.stored) == (1, 1, 1)
    assert first.provenance == "" and first.results
    assert again.provenance.startswith(f"from the evaluation cache {tmp_path / 'c.sqlite'}") and not again.results
    recomputed = C.evaluate(handle, Fidelity.DRAFT, cache=None)
    for ev in (first, recomputed):
        assert bits(again.metrics) == bits(ev.metrics)
        assert (again.statuses, again.messages, again.modules) == (ev.statuses, ev.messages, ev.modules)


def test_changed_design_fidelity_or_code_misses(tmp_path, handle, monkeypatch):
    path = tmp_path / "c.sqlite"
    with EvaluationCache(path) as cache:
        C.evaluate(handle, Fidelity.DRAFT, cache=cache)
        assert C.evaluate(handle, Fidelity.DRAFT, cache=cache).provenance
        other = io.apply_overrides(handle, ["name=handle-b"])
        assert C.evaluate(other, Fidelity.DRAFT, cache=cache).provenance == ""
        assert C.evaluate(handle, Fidelity.DRAFT, cache=cache, only=("stability",)).provenance == ""
        monkeypatch.setattr(C, "code_version", lambda: "another code version")
        assert C.evaluate(handle, Fidelity.DRAFT, cache=cache).provenance == ""
        assert cache.hits == 1 and cache.misses == 4


def test_a_failed_evaluator_is_not_stored(tmp_path, handle, monkeypatch):
    from hapticopt.analysis.handle import zwidth

    def boom(design, *, fidelity):
        raise MemoryError("transient")

    monkeypatch.setattr(zwidth, "evaluate", boom)
    with EvaluationCache(tmp_path / "c.sqlite") as cache:
        ev = C.evaluate(handle, Fidelity.DRAFT, cache=cache)
        assert ev.statuses["zwidth"] == "failed"
        assert cache.stored == 0


def test_reuse_false_computes_and_still_stores(tmp_path, handle):
    with EvaluationCache(tmp_path / "c.sqlite") as cache:
        C.evaluate(handle, Fidelity.DRAFT, cache=cache)
        ev = C.evaluate(handle, Fidelity.DRAFT, cache=cache, reuse=False)
        assert ev.provenance == "" and ev.results
        assert C.evaluate(handle, Fidelity.DRAFT, cache=cache).provenance


@pytest.mark.parametrize("preset, fidelity", [("handle-paper", Fidelity.DRAFT), ("prrr-paper", Fidelity.DRAFT)])
def test_merged_parts_equal_one_evaluation(preset, fidelity):
    """An evaluation computed in two parts (the pipeline's side process and main process) merges into
    the evaluation of all evaluators at once: the same keys in the same order, every float bit."""
    from hapticopt.analysis.registry import EVALUATORS

    design = io.load_preset(preset)
    whole = C.evaluate(design, fidelity, cache=None)
    names = [e.name for e in EVALUATORS[design.device] if str(fidelity) not in e.on_request_at]  # those `whole` ran
    first = tuple(names[1::2])  # interleaved with the rest in the registry's order
    parts = [C.evaluate(design, fidelity, cache=None, only=first),
             C.evaluate(design, fidelity, cache=None, only=tuple(n for n in names if n not in first))]
    merged = C.merge(design, parts[::-1])
    for key in ("metrics", "statuses", "messages", "modules"):
        assert json.dumps(bits(getattr(merged, key))) == json.dumps(bits(getattr(whole, key))), key
    assert list(merged.timings_s) == list(whole.timings_s) and set(merged.results) == set(whole.results)


def test_merge_refuses_overlapping_parts_and_mixed_fidelities(handle):
    a = C.evaluate(handle, Fidelity.DRAFT, cache=None, only=("stability",))
    with pytest.raises(ValueError, match="two parts"):
        C.merge(handle, [a, a])
    with pytest.raises(ValueError, match="different fidelities"):
        C.merge(handle, [a, C.evaluate(handle, Fidelity.STANDARD, cache=None, only=("zwidth",))])


def test_store_keeps_an_evaluation_under_its_key_unless_one_failed(tmp_path, handle):
    ev = C.evaluate(handle, Fidelity.DRAFT, cache=None)
    with EvaluationCache(tmp_path / "c.sqlite") as cache:
        C.store(cache, handle, dataclasses.replace(ev, statuses={**ev.statuses, "zwidth": "failed"}))
        assert C.cached(handle, Fidelity.DRAFT, cache) is None and cache.stored == 0
        C.store(cache, handle, ev)
        hit = C.cached(handle, Fidelity.DRAFT, cache)
        assert hit is not None and bits(hit.metrics) == bits(ev.metrics) and hit.provenance
        assert C.cached(handle, Fidelity.DRAFT, cache, only=("zwidth",)) is None  # another key


# ------------------------------------------------------------------------------------ faults
def test_a_corrupt_file_is_ignored_with_one_warning(tmp_path, handle, capsys):
    path = tmp_path / "c.sqlite"
    path.write_bytes(b"this is not a database" * 100)
    cache = EvaluationCache(path)
    ev = C.evaluate(handle, Fidelity.DRAFT, cache=cache)
    cache.close()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"warning: evaluation cache {path} ignored (")
    assert ev.provenance == "" and ev.statuses["stability"] == "ok"
    assert path.read_bytes() == b"this is not a database" * 100  # the user's file is left as it was


def _digest(path):
    """The database file's bytes (a read-only reader of a WAL database may create the empty -wal/-shm index)."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("edit", ["UPDATE evaluations SET payload = '{\"metrics\": {'",
                                  "UPDATE evaluations SET payload = replace(payload, '\"statuses\"', '\"statuses\" ')"])
def test_an_edited_entry_is_refused_and_the_file_left_unmodified(tmp_path, handle, edit):
    """Issue 37: a hand-edited entry was served silently; now its checksum refuses the file (exit 2)."""
    path = tmp_path / "c.sqlite"
    with EvaluationCache(path) as cache:
        C.evaluate(handle, Fidelity.DRAFT, cache=cache)
    with contextlib.closing(sqlite3.connect(path)) as db, db:
        db.execute(edit)
    before = _digest(path)
    with pytest.raises(InputFileError, match="does not match its checksum"):
        EvaluationCache(path)
    assert _digest(path) == before


def test_an_entry_edited_after_opening_is_a_miss_with_a_warning(tmp_path, handle, capsys):
    path = tmp_path / "c.sqlite"
    with EvaluationCache(path) as cache:
        C.evaluate(handle, Fidelity.DRAFT, cache=cache)
        with contextlib.closing(sqlite3.connect(path)) as db, db:
            db.execute("UPDATE evaluations SET payload = replace(payload, '\"statuses\"', '\"statuses\" ')")
        ev = C.evaluate(handle, Fidelity.DRAFT, cache=cache)
    assert ev.provenance == ""
    assert "checksum" in capsys.readouterr().err


@pytest.mark.parametrize("sql", ["CREATE TABLE other (a)", "CREATE VIEW v AS SELECT 1",
                                 "CREATE TABLE meta (key TEXT, value TEXT); CREATE TABLE evaluations (key)"])
def test_a_foreign_database_is_refused_and_left_unmodified(tmp_path, sql):
    path = tmp_path / "c.sqlite"
    with contextlib.closing(sqlite3.connect(path)) as db:
        db.executescript(sql)
    before = _digest(path)
    with pytest.raises(InputFileError, match="refused, not modified"):
        EvaluationCache(path)
    assert _digest(path) == before


def test_a_link_at_the_cache_or_its_side_files_is_refused(tmp_path):
    target = tmp_path / "elsewhere"
    target.write_text("keep")
    for name in ("c.sqlite", "c.sqlite-wal", "c.sqlite-shm"):
        d = tmp_path / name.replace(".", "_")
        d.mkdir()
        (d / name).symlink_to(target)
        with pytest.raises(InputFileError, match="symbolic link"):
            EvaluationCache(d / "c.sqlite")
    assert target.read_text() == "keep"


def test_a_file_that_cannot_be_opened_is_ignored(tmp_path, handle, capsys):
    """The cache's folder is a file (works as root too, unlike a chmod)."""
    (tmp_path / "afile").write_text("")
    cache = EvaluationCache(tmp_path / "afile" / "c.sqlite")
    assert not cache.enabled and C.evaluate(handle, Fidelity.DRAFT, cache=cache).provenance == ""
    assert "ignored" in capsys.readouterr().err


def test_another_format_is_ignored(tmp_path, capsys):
    path = tmp_path / "c.sqlite"
    EvaluationCache(path).close()
    with contextlib.closing(sqlite3.connect(path)) as db, db:
        db.execute("UPDATE meta SET value = '999' WHERE key = 'format'")
    assert not EvaluationCache(path).enabled
    assert "cache format 999" in capsys.readouterr().err


# ------------------------------------------------------------------------ two processes, a kill
WRITER = """
import sys, time
from hapticopt.optim.cache import EvaluationCache
cache = EvaluationCache(sys.argv[1])
payload = {"metrics": {"x": [0.1] * 2000}, "statuses": {}, "messages": {}, "modules": {}, "timings_s": {}}
for i in range(int(sys.argv[3])):
    cache.store(f"{sys.argv[2]}-{i % 50}", payload, device="d", design="n", fidelity="draft", only=None,
                written_by=sys.argv[2])
    if cache.disabled:
        print("DISABLED", cache.disabled)
        sys.exit(1)
    print(i, flush=True)
"""


def test_two_processes_write_one_cache(tmp_path):
    path = tmp_path / "c.sqlite"
    procs = [subprocess.Popen([sys.executable, "-c", WRITER, str(path), tag, "200"], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for tag in ("a", "b")]
    for p in procs:
        out, err = p.communicate(timeout=120)
        assert p.returncode == 0, out + err
        assert err == ""
    with EvaluationCache(path) as cache:
        assert all(cache.lookup(f"{tag}-{i}") is not None for tag in "ab" for i in range(50))


def test_a_killed_writer_leaves_a_sound_cache(tmp_path):
    path = tmp_path / "c.sqlite"
    p = subprocess.Popen([sys.executable, "-c", WRITER, str(path), "k", "100000"], stdout=subprocess.PIPE, text=True)
    assert p.stdout is not None
    for _ in range(30):  # let it commit a few entries, then kill it mid-stream
        p.stdout.readline()
    os.kill(p.pid, signal.SIGKILL)
    p.wait(30)
    p.stdout.close()
    with contextlib.closing(sqlite3.connect(path)) as db, db:
        assert db.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        rows = db.execute("SELECT payload FROM evaluations").fetchall()
    assert len(rows) >= 29 and all(len(json.loads(r[0])["metrics"]["x"]) == 2000 for r in rows)
    with EvaluationCache(path) as cache:
        assert cache.enabled and cache.lookup("k-0") is not None
