"""The registry of systems: an explicit table from system id to the module that defines it.

Adding a system is one module (its class, ``MODEL = TheClass``), one line in ``SYSTEMS`` and
its test file. A module is imported only when its id is asked for, so a scene never imports or
compiles systems it does not use, and a system module may itself import ``mechsim.systems``.
Code outside the package (a plug-in, a test) adds a system with :func:`register`.
"""

from __future__ import annotations

import importlib
import re
from typing import Any

from mechsim.errors import UnknownSystemError
from mechsim.params import shown
from mechsim.systems.base import Model

#: System id -> module whose ``MODEL`` is the system's class.
SYSTEMS: dict[str, str] = {
    "atwood": "mechsim.systems.atwood",
    "bead_on_wire": "mechsim.systems.bead_on_wire",
    "central_force": "mechsim.systems.central_force",
    "central_force_3d": "mechsim.systems.central_force_3d",
    "charged_particle": "mechsim.systems.charged_particle",
    "collision": "mechsim.systems.collision",
    "coupled_oscillators": "mechsim.systems.coupled_oscillators",
    "cr3bp": "mechsim.systems.cr3bp",
    "damped_oscillator": "mechsim.systems.damped_oscillator",
    "double_pendulum": "mechsim.systems.double_pendulum",
    "drag_projectile": "mechsim.systems.drag_projectile",
    "driven_oscillator": "mechsim.systems.driven_oscillator",
    "dumbbell": "mechsim.systems.dumbbell",
    "forced_particle": "mechsim.systems.forced_particle",
    "gas_in_box": "mechsim.systems.gas_in_box",
    "geodesic": "mechsim.systems.geodesic",
    "harmonic_oscillator": "mechsim.systems.harmonic_oscillator",
    "kepler": "mechsim.systems.kepler",
    "knife_edge": "mechsim.systems.knife_edge",
    "lrc_circuit": "mechsim.systems.lrc_circuit",
    "moving_coordinates": "mechsim.systems.moving_coordinates",
    "moving_frames": "mechsim.systems.moving_frames",
    "noninertial_frame": "mechsim.systems.noninertial_frame",
    "orbit_frames": "mechsim.systems.orbit_frames",
    "oscillator_chain": "mechsim.systems.oscillator_chain",
    "paraboloid_bead": "mechsim.systems.paraboloid_bead",
    "pendulum": "mechsim.systems.pendulum",
    "periodic_drive": "mechsim.systems.periodic_drive",
    "planar_oscillator": "mechsim.systems.planar_oscillator",
    "power_law_orbit": "mechsim.systems.power_law_orbit",
    "rigid_body": "mechsim.systems.rigid_body",
    "rotating_frame": "mechsim.systems.rotating_frame",
    "rotating_hoop": "mechsim.systems.rotating_hoop",
    "rotating_spring": "mechsim.systems.rotating_spring",
    "scattering": "mechsim.systems.scattering",
    "small_oscillations": "mechsim.systems.small_oscillations",
    "sphere_slide": "mechsim.systems.sphere_slide",
    "spherical_pendulum": "mechsim.systems.spherical_pendulum",
    "spring_pendulum": "mechsim.systems.spring_pendulum",
    "symmetric_top": "mechsim.systems.symmetric_top",
    "three_body": "mechsim.systems.three_body",
    "two_body_field": "mechsim.systems.two_body_field",
}

_ID = re.compile(r"^[a-z][a-z0-9_]{0,63}$")
#: Classes registered at run time (``register`` with a class), by id.
_CLASSES: dict[str, type[Model]] = {}


def register(system_id: str, model: type[Model] | str) -> None:
    """Add a system: ``model`` is its class, or the name of a module whose ``MODEL`` is the
    class (imported when the id is first asked for). The id must be new, lower-case snake_case,
    and equal to the class's ``id``."""
    if not isinstance(system_id, str) or not _ID.match(system_id):
        raise ValueError(f"system id {system_id!r}: must be lower-case snake_case")
    if system_id in SYSTEMS or system_id in _CLASSES:
        raise ValueError(f"system id {system_id!r} is already registered")
    if isinstance(model, str):
        SYSTEMS[system_id] = model
        return
    if not (isinstance(model, type) and issubclass(model, Model)):
        raise TypeError(f"system {system_id!r}: a Model subclass or a module name, "
                        f"not {model!r}")
    if getattr(model, "id", None) != system_id:
        raise ValueError(f"system {system_id!r}: the class's id is {getattr(model, 'id', None)!r}")
    _CLASSES[system_id] = model


def unregister(system_id: str) -> None:
    """Remove a system added with :func:`register` (or a table entry); unknown ids are
    ignored."""
    _CLASSES.pop(system_id, None)
    SYSTEMS.pop(system_id, None)


def system_ids() -> list[str]:
    return sorted({*SYSTEMS, *_CLASSES})


def system_class(system_id: str) -> type[Model]:
    if isinstance(system_id, str) and system_id in _CLASSES:
        return _CLASSES[system_id]
    if not isinstance(system_id, str) or system_id not in SYSTEMS:
        raise UnknownSystemError(shown(system_id) if not isinstance(system_id, str)
                                 else shown(system_id)[1:-1], system_ids())
    cls = importlib.import_module(SYSTEMS[system_id]).MODEL
    if getattr(cls, "id", None) != system_id:
        raise TypeError(f"{SYSTEMS[system_id]}.MODEL has id {getattr(cls, 'id', None)!r}, "
                        f"registered as {system_id!r}")
    return cls  # type: ignore[no-any-return]


def load_system(system_id: str, **params: Any) -> Model:
    """A model of ``system_id`` with validated parameters (raises ParameterError)."""
    return system_class(system_id)(**params)
