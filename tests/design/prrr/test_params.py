"""design/prrr/params.py: a design and its sections are plain frozen dataclasses, hashed and compared by
their fields, carrying no other state (the caches keyed by a design rely on that)."""

from __future__ import annotations

import copy
import dataclasses
import pickle

import pytest

from hapticopt.design.prrr import params as P


def _field_tuple_hash(d: P.PrrrDesign) -> int:
    """What ``dataclass(frozen=True)`` generates: the hash of the tuple of the fields, in order."""
    return hash((d.name, d.description, d.geometry, d.actuator, d.end_effector, d.structure, d.sea_module))


def test_the_hash_is_the_dataclass_hash_of_the_fields():
    d = P.PrrrDesign(geometry=P.PrrrGeometry(d3=0.081))
    assert hash(d) == _field_tuple_hash(d)
    for name in P.PrrrDesign.SECTIONS:
        sec = getattr(d, name)
        assert hash(sec) == hash(tuple(getattr(sec, f.name) for f in dataclasses.fields(sec)))
    # the compared fields are exactly the seven above (a new field must enter the hash)
    assert [f.name for f in dataclasses.fields(P.PrrrDesign)] == [
        "name", "description", "geometry", "actuator", "end_effector", "structure", "sea_module"]


def test_a_design_carries_nothing_but_its_fields():
    d = P.PrrrDesign()
    hash(d)
    fields = {f.name for f in dataclasses.fields(d)}
    assert set(vars(d)) == fields
    for name in P.PrrrDesign.SECTIONS:
        sec = getattr(d, name)
        hash(sec)
        assert set(vars(sec)) == {f.name for f in dataclasses.fields(sec)}


def test_equal_fields_are_one_key_and_copies_are_equal():
    a, b = P.PrrrDesign(), P.PrrrDesign()
    assert a == b and hash(a) == hash(b) and len({a, b}) == 1
    c = dataclasses.replace(a, geometry=dataclasses.replace(a.geometry, d4=0.0801))
    assert c != a and hash(c) == _field_tuple_hash(c)
    assert {a: 1, c: 2}[P.PrrrDesign(geometry=c.geometry)] == 2
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.name = "other"  # type: ignore[misc]
    for other in (copy.copy(a), copy.deepcopy(a), pickle.loads(pickle.dumps(a))):
        assert other == a and hash(other) == hash(a)
