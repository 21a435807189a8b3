"""Errors a user can cause: each carries a one-line message naming the field and the reason."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


def one_line(text: str) -> str:
    """``text`` with control characters (newlines from hostile input, ...) escaped."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``n`` and ``noun`` in the number ``n`` asks for: ``1 system``, ``2 systems``."""
    if n == 1:
        return f"{n} {noun}"
    return f"{n} {plural or (noun + 'es' if noun.endswith('s') else noun + 's')}"


def did_you_mean(name: str, known: Iterable[str], what: str = "known") -> str:
    """What to say after an unknown ``name``: ``: did you mean 'x'? (known: a, b, c)`` where
    one of ``known`` is close, else `` (known: a, b, c)``."""
    names = sorted(set(known))
    close = difflib.get_close_matches(name, names, n=1, cutoff=0.6) if len(name) <= 100 else []
    hint = f": did you mean {close[0]!r}?" if close else ""
    return f"{hint} ({what}: {', '.join(names)})"


class MechsimError(Exception):
    """Base of every error mechsim reports to a user as one line (never a traceback)."""

    def __str__(self) -> str:
        return one_line(super().__str__())


class ParameterError(MechsimError, ValueError):
    """A parameter, initial condition or scene field is unknown, mistyped or out of range."""

    def __init__(self, field: str, reason: str) -> None:
        self.field = field
        self.reason = reason
        super().__init__(f"{field}: {reason}")


class UnknownSystemError(MechsimError, KeyError):
    """No system has the requested id."""

    def __init__(self, system_id: str, known: list[str]) -> None:
        self.system_id = system_id
        super().__init__(system_id)
        self._msg = f"unknown system '{system_id}'{did_you_mean(system_id, known)}"

    def __str__(self) -> str:
        return one_line(self._msg)


class IntegrationError(MechsimError, RuntimeError):
    """The integrator stopped: non-finite state, step-size underflow or too many steps."""


class RosStartError(MechsimError):
    """ROS cannot start in this environment (rclpy's start-up failed, an unusable domain id):
    the environment's problem, said in one line."""
