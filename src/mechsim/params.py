"""Typed, validated parameters with units: one spelling for the API, scenes, CLI and ROS."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from mechsim.errors import ParameterError

Value = float | int | str | bool


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
        name = self.name
        kind = self.kind
        if kind is bool:
            if isinstance(value, bool):
                return value
            if isinstance(value, str) and value.lower() in ("true", "false"):
                return value.lower() == "true"
            raise ParameterError(name, f"must be true or false (got {value!r})")
        if kind is str:
            if not isinstance(value, str):
                raise ParameterError(name, f"must be a string (got {value!r})")
            if self.choices is not None and value not in self.choices:
                raise ParameterError(
                    name, f"must be one of {', '.join(self.choices)} (got {value!r})")
            return value
        if isinstance(value, bool):
            raise ParameterError(name, f"must be a number (got {value!r})")
        if isinstance(value, str):
            try:
                value = float(value)
            except ValueError:
                raise ParameterError(name, f"must be a number (got {value!r})") from None
        if not isinstance(value, int | float):
            raise ParameterError(name, f"must be a number (got {value!r})")
        if kind is int:
            if isinstance(value, float) and not value.is_integer():
                raise ParameterError(name, f"must be an integer (got {value!r})")
            number: float | int = int(value)
        else:
            number = float(value)
        if not math.isfinite(number):
            raise ParameterError(name, f"must be finite (got {value!r})")
        lo, hi = self.minimum, self.maximum
        if lo is not None and (number < lo or (self.exclusive_minimum and number == lo)):
            op = ">" if self.exclusive_minimum else ">="
            raise ParameterError(name, f"must be {op} {lo:g} (got {number:g})")
        if hi is not None and (number > hi or (self.exclusive_maximum and number == hi)):
            op = "<" if self.exclusive_maximum else "<="
            raise ParameterError(name, f"must be {op} {hi:g} (got {number:g})")
        return number

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


def flatten(values: Mapping[str, Any]) -> dict[str, Any]:
    """Flatten nested mappings: ``{"initial": {"angle": 1}}`` -> ``{"initial.angle": 1}``."""
    out: dict[str, Any] = {}
    for key, value in values.items():
        if not isinstance(key, str):
            raise ParameterError(str(key), "parameter names must be strings")
        if isinstance(value, Mapping):
            for sub, v in flatten(value).items():
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
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise ParameterError(key, f"unknown parameter{hint}")
    return {name: (p.validate(given[name]) if name in given else p.default)
            for name, p in table.items()}
