"""The one exceptions module of hapticopt.

Every user-facing failure is one of these; its message is a single line naming the field,
the value, and what is allowed (with its unit). The CLI turns them into exit code 2.
"""

from __future__ import annotations

import re
import reprlib


class HapticoptError(Exception):
    """Base class of every error hapticopt raises on purpose."""


class InvalidDesign(HapticoptError, ValueError):
    """A design value is missing, unknown, non-numeric or out of its allowed range."""


class InputFileError(HapticoptError, ValueError):
    """An input file is missing, unreadable or malformed."""


class UnknownName(HapticoptError, KeyError):
    """A preset, scene, problem or metric name that does not exist."""

    def __str__(self) -> str:  # KeyError quotes its message; we want the plain line
        return str(self.args[0]) if self.args else ""


class InvalidInput(HapticoptError, ValueError):
    """A non-design input (CLI option, scene or problem field) is invalid."""


#: how values are echoed in messages: a 10⁶-element array or a megabyte string becomes one short line
_REPR = reprlib.Repr()
_REPR.maxstring = 60
_REPR.maxother = 60
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 6
_REPR.maxlevel = 2
_REPR.maxlong = 40


#: strings that look like a credential pasted into the wrong field: well-known token prefixes (GitHub,
#: AWS, Slack, OpenAI/Stripe-style keys, PEM blocks) or a long unbroken run mixing upper, lower and digits
_SECRET = re.compile(r"(?<![A-Za-z0-9])(gh[pousr]_|github_pat_|AKIA[0-9A-Z]{12}|ASIA[0-9A-Z]{12}|xox[abposr]-|sk-|sk_live_|"
                     r"rk_live_|-----BEGIN)")
_TOKEN = re.compile(r"[A-Za-z0-9+/_=-]{24,}")


def looks_secret(text: str) -> bool:
    """Whether ``text`` looks like a credential (so that an error message does not echo it into a log)."""
    if _SECRET.search(text):
        return True
    return any(re.search("[A-Z]", t) and re.search("[a-z]", t) and re.search("[0-9]", t)
               for t in _TOKEN.findall(text))


def short(value: object) -> str:
    """``repr(value)`` shortened (:mod:`reprlib`) for a one-line message; a string that looks like a
    credential is not echoed, only its length."""
    if isinstance(value, str) and looks_secret(value):
        return f"<{len(value)} characters that look like a credential, not shown>"
    return _REPR.repr(value)


def short_key(key: object) -> str:
    """A key as written (``colour``), or shortened/quoted when it is long or has odd characters."""
    if isinstance(key, str) and len(key) <= 40 and key.isprintable():
        return key
    return short(key)
