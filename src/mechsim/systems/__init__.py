"""Registry of systems. A system module is imported only when its id is asked for."""

from __future__ import annotations

import importlib
from typing import Any

from mechsim.errors import UnknownSystemError
from mechsim.systems.base import Model

# id -> "module:Class" (module under mechsim.systems). Keep sorted by id.
REGISTRY: dict[str, str] = {
    "driven_oscillator": "driven_oscillator:DrivenOscillator",
    "kepler": "kepler:Kepler",
    "pendulum": "pendulum:Pendulum",
}


def system_ids() -> list[str]:
    return sorted(REGISTRY)


def system_class(system_id: str) -> type[Model]:
    if not isinstance(system_id, str) or system_id not in REGISTRY:
        raise UnknownSystemError(str(system_id), list(REGISTRY))
    module, cls = REGISTRY[system_id].split(":")
    return getattr(importlib.import_module(f"mechsim.systems.{module}"), cls)


def load_system(system_id: str, **params: Any) -> Model:
    """A model of ``system_id`` with validated parameters (raises ParameterError)."""
    return system_class(system_id)(**params)
