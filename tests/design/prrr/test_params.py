"""design/prrr/params.py: the kept hash of a design and of its sections (computed once) is the dataclass's
hash of the fields and cannot go stale or travel to another process."""

from __future__ import annotations

import copy
import dataclasses
import os
import pickle
import subprocess
import sys

import pytest

from hapticopt.design.prrr import params as P


def _field_tuple_hash(d: P.PrrrDesign) -> int:
    """What ``dataclass(frozen=True)`` generates: the hash of the tuple of the fields, in order."""
    return hash((d.name, d.description, d.geometry, d.actuator, d.end_effector, d.structure, d.sea_module))


def test_the_kept_hash_is_the_dataclass_hash_of_the_fields():
    d = P.PrrrDesign(geometry=P.PrrrGeometry(d3=0.081))
    assert hash(d) == _field_tuple_hash(d)
    assert hash(d) == hash(d) == d.__dict__[P._HASH_KEPT]  # kept after the first call
    # each section: the tuple of its fields, as the generated hash
    for name in P.PrrrDesign.SECTIONS:
        sec = getattr(d, name)
        assert hash(sec) == hash(tuple(getattr(sec, f.name) for f in dataclasses.fields(sec)))
    # the compared fields are exactly the seven above (a new field must enter the hash)
    assert [f.name for f in dataclasses.fields(P.PrrrDesign)] == [
        "name", "description", "geometry", "actuator", "end_effector", "structure", "sea_module"]


def test_equality_is_the_fields_and_ignores_the_kept_hash():
    a, b = P.PrrrDesign(), P.PrrrDesign()
    hash(a)  # a keeps its hash, b does not yet
    assert a == b and hash(a) == hash(b)
    assert len({a, b}) == 1
    c = dataclasses.replace(a, geometry=dataclasses.replace(a.geometry, d4=0.0801))
    assert c != a
    assert P._HASH_KEPT not in c.__dict__ and P._HASH_KEPT not in c.geometry.__dict__  # built from the fields
    assert hash(c) == _field_tuple_hash(c) != hash(a)
    assert {a: 1, c: 2}[P.PrrrDesign(geometry=c.geometry)] == 2


def test_the_kept_hash_cannot_go_stale():
    d = P.PrrrDesign()
    h = hash(d)
    with pytest.raises(dataclasses.FrozenInstanceError):
        d.name = "other"  # type: ignore[misc]
    assert hash(d) == h == _field_tuple_hash(d)
    for other in (copy.copy(d), copy.deepcopy(d), pickle.loads(pickle.dumps(d))):
        assert P._HASH_KEPT not in other.__dict__  # copies compute it afresh
        assert other == d and hash(other) == h
    hash(d.geometry)
    g = pickle.loads(pickle.dumps(d.geometry))
    assert P._HASH_KEPT not in g.__dict__ and g == d.geometry and hash(g) == hash(d.geometry)


def test_a_pickled_design_hashes_by_the_other_process_strings():
    """The hash of the name string differs between processes (hash randomisation): a design sent to a
    worker must not carry this process's hash."""
    d = P.PrrrDesign(name="kept-hash-test")
    hash(d)
    code = ("import pickle, sys; from hapticopt.design.prrr import params as P; "
            "d = pickle.loads(sys.stdin.buffer.read()); "
            "f = (d.name, d.description, d.geometry, d.actuator, d.end_effector, d.structure, d.sea_module); "
            "print(hash(d) == hash(f), P._HASH_KEPT in d.__dict__ and d.__dict__[P._HASH_KEPT] == hash(d))")
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    out = subprocess.run([sys.executable, "-c", code], input=pickle.dumps(d), capture_output=True, env=env,
                         check=True).stdout.decode().split()
    assert out == ["True", "True"]
