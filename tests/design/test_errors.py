"""design/errors.py: how a value is echoed in a one-line error."""

from __future__ import annotations

import pytest

from hapticopt.design.errors import looks_secret, short


@pytest.mark.parametrize("text", [
    "ghp_A1b2C3d4E5f6G7h8I9j0K1l2M3n4O5p6Q7r8",  # GitHub personal token shape
    "AKIAIOSFODNN7EXAMPLE",  # AWS's documented example access key id
    "xoxb-123456789012-abcdefABCDEF",
    "sk-proj-abc",
    "-----BEGIN OPENSSH PRIVATE KEY-----",
    "Zm9vYmFyQmF6UXV4MTIzNDU2Nzg5MGFi",  # a long run mixing upper, lower and digits
])
def test_a_credential_looking_value_is_not_echoed(text):
    """Issue 37 item 9: a secret pasted into a numeric field was echoed in the error (and so into logs)."""
    assert looks_secret(text)
    shown = short(text)
    assert text not in shown and text[:8] not in shown and f"<{len(text)} characters" in shown


@pytest.mark.parametrize("text", ["abc", "prrr-paper", "geometry.r_p_mm", "1e-300", "beta-isotropic", "task-2", "disk-full",
                                  "0123456789abcdef0123456789abcdef"])  # a lower-case hex digest is not hidden
def test_ordinary_values_are_echoed(text):
    assert not looks_secret(text) and short(text) == repr(text)


def test_long_values_are_shortened():
    assert len(short("x" * 10_000)) < 80 and len(short(list(range(10**4)))) < 80
