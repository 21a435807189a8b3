"""Registry of systems: system id == module name under ``mechsim.systems``; the module's
``MODEL`` is the model class. A module is imported only when its id is asked for, so a scene
never imports or compiles systems it does not use."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

from mechsim.errors import UnknownSystemError
from mechsim.systems.base import Model

_NOT_SYSTEMS = {"base", "lagrangian", "direct"}


def system_ids() -> list[str]:
    here = Path(__file__).parent
    return sorted(p.stem for p in here.glob("*.py")
                  if not p.stem.startswith("_") and p.stem not in _NOT_SYSTEMS)


def system_class(system_id: str) -> type[Model]:
    known = system_ids()
    if not isinstance(system_id, str) or system_id not in known:
        raise UnknownSystemError(str(system_id), known)
    return importlib.import_module(f"mechsim.systems.{system_id}").MODEL  # type: ignore[no-any-return]


def load_system(system_id: str, **params: Any) -> Model:
    """A model of ``system_id`` with validated parameters (raises ParameterError)."""
    return system_class(system_id)(**params)
