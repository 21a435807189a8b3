"""Typed, validated parameters with units: one spelling for the API, scenes, CLI and ROS.

Besides the parameters of each system, this module holds the one definition of every run
setting's range (``PUBLISH_RATE``, ``TOLERANCE``, ``REAL_TIME_FACTOR``, ``CONSTRAINT_LIMIT``,
``WARN_DRIFT``, ``ERROR_DRIFT``, ``DURATION``): the CLI, scene files and the nodes' ROS parameter
descriptors all validate against these, so nothing is accepted by one and refused by another.
Values from outside are shown in messages through :func:`shown` (bounded, one line).
"""

from __future__ import annotations

import math
import reprlib
import unicodedata
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from mechsim.errors import ParameterError, did_you_mean

Value = float | int | str | bool

# ROS 2 integer parameters are 64-bit.
INT_MIN, INT_MAX = -(2**63), 2**63 - 1

_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxlist, _REPR.maxtuple, _REPR.maxdict = 2, 4, 4, 4
_REPR.maxstring, _REPR.maxother = 60, 60
_SHOWN_MAX = 80


def shown(value: Any) -> str:
    """``repr(value)`` bounded in size and time, for error messages about outside input: huge
    integers are described by their size, containers are cut after a few items and levels (a
    YAML alias bomb is never expanded), long strings are truncated."""
    if isinstance(value, bool) or value is None:
        return repr(value)
    if isinstance(value, int):
        if value.bit_length() > 64:
            digits = int(value.bit_length() * math.log10(2)) + 1
            return f"{'-' if value < 0 else ''}an integer of about {digits} digits"
        return repr(value)
    try:
        text = _REPR.repr(value)
    except Exception:  # noqa: BLE001 - a value that cannot even be shown is named by its type
        text = f"<{type(value).__name__}>"
    return text if len(text) <= _SHOWN_MAX else text[: _SHOWN_MAX - 3] + "..."


def check_text(field: str, value: Any, max_length: int = 4096) -> str:
    """``value`` as a name or path from outside: a string of at most ``max_length`` characters
    without control, format or unassigned characters (NUL, newlines, escape sequences,
    bidirectional overrides, lone surrogates)."""
    if not isinstance(value, str):
        raise ParameterError(field, f"must be a string (got {shown(value)})")
    if not value:
        raise ParameterError(field, "must not be empty")
    if len(value) > max_length:
        raise ParameterError(field, f"longer than {max_length} characters")
    for c in value:
        if unicodedata.category(c).startswith("C"):
            raise ParameterError(field, f"contains the control character {c!r}")
    return value


@dataclass(frozen=True)
class Parameter:
    """One named parameter. Numbers are SI (REP-103); ``unit`` is shown to users."""

    name: str
    default: Value
    unit: str = ""
    description: str = ""
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: bool = False
    exclusive_maximum: bool = False
    choices: tuple[str, ...] | None = None

    @property
    def kind(self) -> type:
        return type(self.default)

    @property
    def is_numeric(self) -> bool:
        return self.kind in (float, int)

    def validate(self, value: Any) -> Value:
        """Return ``value`` converted to this parameter's type or raise ParameterError."""
        if self.kind is bool:
            return self._boolean(value)
        if self.kind is str:
            return self._text(value)
        return self._within_range(self._number(value))

    def _boolean(self, value: Any) -> bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.lower() in ("true", "false"):
            return value.lower() == "true"
        raise ParameterError(self.name, f"must be true or false (got {shown(value)})")

    def _text(self, value: Any) -> str:
        if not isinstance(value, str):
            raise ParameterError(self.name, f"must be a string (got {shown(value)})")
        if self.choices is not None and value not in self.choices:
            raise ParameterError(
                self.name, f"must be one of {', '.join(self.choices)} (got {shown(value)})")
        if self.choices is None:
            check_text(self.name, value, MAX_TEXT)
        return value

    def _number(self, value: Any) -> float | int:
        """``value`` as a finite number of this parameter's type (a string is read as one)."""
        name = self.name
        if isinstance(value, bool):
            raise ParameterError(name, f"must be a number (got {shown(value)})")
        if isinstance(value, str):
            if len(value) > 100:  # no number needs more; bounds float()'s work
                raise ParameterError(name, f"must be a number (got {shown(value)})")
            try:
                value = float(value)
            except ValueError:
                raise ParameterError(name, f"must be a number (got {shown(value)})") from None
        if not isinstance(value, int | float):
            raise ParameterError(name, f"must be a number (got {shown(value)})")
        if isinstance(value, int) and not INT_MIN <= value <= INT_MAX:
            raise ParameterError(name, f"out of range (got {shown(value)})")
        if self.kind is int:
            return self._integer(value)
        number = float(value)
        if not math.isfinite(number):
            raise ParameterError(name, f"must be finite (got {shown(value)})")
        return number

    def _integer(self, value: float | int) -> int:
        if isinstance(value, float) and not (math.isfinite(value) and value.is_integer()):
            raise ParameterError(self.name, f"must be an integer (got {shown(value)})")
        if isinstance(value, float) and not INT_MIN <= value <= INT_MAX:
            raise ParameterError(self.name, f"out of range (got {shown(value)})")
        return int(value)

    def _within_range(self, number: float | int) -> float | int:
        lo, hi = self.minimum, self.maximum
        if lo is not None and (number < lo or (self.exclusive_minimum and number == lo)):
            op = ">" if self.exclusive_minimum else ">="
            raise ParameterError(self.name, f"must be {op} {lo:g} (got {number:g})")
        if hi is not None and (number > hi or (self.exclusive_maximum and number == hi)):
            op = "<" if self.exclusive_maximum else "<="
            raise ParameterError(self.name, f"must be {op} {hi:g} (got {number:g})")
        return number

    def check(self, value: Any, field: str) -> Value:
        """:meth:`validate` with errors naming ``field`` (a scene key, a CLI option)."""
        try:
            return self.validate(value)
        except ParameterError as e:
            raise ParameterError(field, e.reason) from None

    def describe(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name, "default": self.default, "unit": self.unit,
                               "description": self.description, "type": self.kind.__name__}
        if self.minimum is not None:
            out["minimum"] = self.minimum
            out["exclusive_minimum"] = self.exclusive_minimum
        if self.maximum is not None:
            out["maximum"] = self.maximum
            out["exclusive_maximum"] = self.exclusive_maximum
        if self.choices is not None:
            out["choices"] = list(self.choices)
        return out


def positive(name: str, default: float, unit: str, description: str) -> Parameter:
    """A strictly positive number (masses, lengths, spring constants)."""
    return Parameter(name, float(default), unit, description, minimum=0.0, exclusive_minimum=True)


def nonnegative(name: str, default: float, unit: str, description: str) -> Parameter:
    return Parameter(name, float(default), unit, description, minimum=0.0)


def number(name: str, default: float, unit: str, description: str,
           minimum: float | None = None, maximum: float | None = None) -> Parameter:
    return Parameter(name, float(default), unit, description, minimum=minimum, maximum=maximum)


def flatten(values: Mapping[str, Any], _depth: int = 0) -> dict[str, Any]:
    """Flatten nested mappings: ``{"initial": {"angle": 1}}`` -> ``{"initial.angle": 1}``."""
    out: dict[str, Any] = {}
    if _depth > 4:
        raise ParameterError("parameters", "nested too deeply")
    for key, value in values.items():
        if not isinstance(key, str):
            raise ParameterError(shown(key), "parameter names must be strings")
        if isinstance(value, Mapping):
            for sub, v in flatten(value, _depth + 1).items():
                out[f"{key}.{sub}"] = v
        else:
            out[key] = value
    return out


def resolve(spec: Iterable[Parameter], values: Mapping[str, Any]) -> dict[str, Value]:
    """Defaults overlaid with ``values``; unknown names and bad values raise ParameterError."""
    table = {p.name: p for p in spec}
    given = flatten(values)
    for key in given:
        if key not in table:
            close = [n for n in table if n.split(".")[-1] == key.split(".")[-1]]
            name = key if len(key) <= 60 else shown(key)
            hint = (f": did you mean {close[0]!r}? (parameters: {', '.join(table)})" if close
                    else did_you_mean(name, table, "parameters"))
            raise ParameterError(name, f"unknown parameter{hint}")
    return {name: (p.validate(given[name]) if name in given else p.default)
            for name, p in table.items()}


# --- run settings: one definition of each range for the CLI, scenes and the nodes -------------
#: Longest free-text parameter value (a curve expression, ...).
MAX_TEXT = 1000

PUBLISH_RATE = Parameter("publish_rate", 100.0, "Hz", "samples per second of simulation time",
                         minimum=0.01, maximum=10000.0)
TOLERANCE = Parameter("tolerance", 1e-10, "", "integrator tolerance (relative and absolute)",
                      minimum=1e-15, maximum=0.99)
REAL_TIME_FACTOR = Parameter("real_time_factor", 1.0, "",
                             "simulated seconds per wall second; 0: as fast as possible "
                             "(a node then is stepped by its caller)", minimum=0.0, maximum=1e6)
CONSTRAINT_LIMIT = Parameter("constraint_limit", 1e-2, "",
                             "hard limit on an enforced constraint residual, relative to "
                             "max(1, max|q|); past it the system stops",
                             minimum=1e-12, maximum=1e6)
WARN_DRIFT = Parameter("warn_drift", 1e-6, "",
                       "relative drift of a conservation law that gives WARN",
                       minimum=0.0, maximum=1.0, exclusive_minimum=True)
ERROR_DRIFT = Parameter("error_drift", 1e-3, "",
                        "relative drift of a conservation law that gives ERROR",
                        minimum=0.0, maximum=1.0, exclusive_minimum=True)
# Stamps are simulation time + an offset in builtin_interfaces/Time, whose seconds are int32.
DURATION = Parameter("duration", 10.0, "s", "simulated seconds", minimum=0.0, maximum=1e9,
                     exclusive_minimum=True)
# The graph check before a command's nodes start (``mechsim.ros.launch``); 2 s: see there.
DISCOVERY_WINDOW = Parameter("graph_wait", 2.0, "s",
                             "seconds of DDS discovery in which a start is refused if its "
                             "instance name or /clock is in use (0: no check)",
                             minimum=0.0, maximum=600.0)
# The effort input of a simulator node (``<ns>/effort``, see ``mechsim.ros.simulator``).
EFFORT_TIMEOUT = Parameter("effort_timeout", 0.5, "s",
                           "simulated seconds an effort command is held after it takes effect; "
                           "then the effort returns to zero until the next command",
                           minimum=0.0, maximum=1e9, exclusive_minimum=True)
EFFORT_WAIT = Parameter("effort_wait", 1.0, "s",
                        "stepped (fast) runs with an effort publisher: wall seconds the node "
                        "waits after each sample for the next command (0: never waits)",
                        minimum=0.0, maximum=60.0)
