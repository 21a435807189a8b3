"""The explicit system registry, and a system added from outside the package the public way.

The throw-away system below (a particle on a zero-length spring in a gravity field, the system
of docs/adding_a_system.md under an id of its own, so that adding the example to the package
leaves these tests as they are) is one class and one ``register`` call; its energy,
conservation laws, ``simulate`` output, frames and a diagnostics-checked run through the node
graph come for free. Everything is checked against the closed-form solution, not against the
engine that produced it."""

from __future__ import annotations

import ast
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import sympy as sp

import mechsim
from mechsim import systems
from mechsim.errors import UnknownSystemError
from mechsim.outputs.sink import Capabilities  # noqa: E402
from mechsim.params import nonnegative, number, positive
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

SYSTEMS_DIR = Path(systems.__file__).parent


class SpringParticle(LagrangianModel):
    """A particle of mass m on a spring of zero rest length anchored at the origin, in gravity
    g along −z: ẍ = −ω²x, z̈ = −ω²z − g with ω² = k/m (the test's own example system)."""

    id = "test_spring_particle"
    title = "Particle on a spring in a gravity field"
    source = "tests/test_registry.py (the worked example of docs/adding_a_system.md)"
    parameters = (
        positive("mass", 2.0, "kg", "mass m"),
        positive("spring_constant", 8.0, "N/m", "spring constant k (rest length 0)"),
        nonnegative("gravity", 9.81, "m/s^2", "gravitational acceleration g (along −z)"),
        number("initial.x", 0.3, "m", "initial x"),
        number("initial.z", -0.5, "m", "initial z"),
        number("initial_rate.x", 0.0, "m/s", "initial ẋ"),
        number("initial_rate.z", 0.4, "m/s", "initial ż"),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        m, k, g = b.param("mass"), b.param("spring_constant"), b.param("gravity")
        x, vx = b.coordinate("x", "m")
        z, vz = b.coordinate("z", "m")
        b.kinetic = m * (vx**2 + vz**2) / 2
        b.potential = k * (x**2 + z**2) / 2 + m * g * z
        # Angular momentum about the equilibrium (0, −mg/k): the force is central about it.
        b.invariant("angular_momentum", "kg*m^2/s", m * (x * vz - (z + m * g / k) * vx))
        b.frame("particle", "world", (x, sp.Integer(0), z))

    def time_scale(self) -> float:
        return 2 * math.pi * math.sqrt(self.value("mass") / self.value("spring_constant"))


M, K, G = 2.0, 8.0, 9.81
X0, Z0, VX0, VZ0 = 0.3, -0.5, 0.0, 0.4
W = math.sqrt(K / M)
Z_EQ = -M * G / K


def closed_form(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    c, s = np.cos(W * t), np.sin(W * t)
    x = X0 * c + VX0 / W * s
    z = Z_EQ + (Z0 - Z_EQ) * c + VZ0 / W * s
    vx = -X0 * W * s + VX0 * c
    vz = -(Z0 - Z_EQ) * W * s + VZ0 * c
    return x, z, vx, vz


@pytest.fixture
def spring_particle() -> Iterator[None]:
    systems.register("test_spring_particle", SpringParticle)
    try:
        yield
    finally:
        systems.unregister("test_spring_particle")


def test_every_system_module_is_registered() -> None:
    """A module under systems/ that defines MODEL is in the table under its class's id, and
    the table names nothing else."""
    found = {}
    for path in sorted(SYSTEMS_DIR.glob("*.py")):
        tree = ast.parse(path.read_text())
        if any(isinstance(n, ast.Assign) and any(getattr(t, "id", "") == "MODEL"
                                                  for t in n.targets) for n in tree.body):
            found[f"mechsim.systems.{path.stem}"] = path
    assert set(systems.SYSTEMS.values()) == set(found)
    for sid in systems.SYSTEMS:
        assert systems.system_class(sid).id == sid


def test_registry_rejects_bad_entries() -> None:
    with pytest.raises(UnknownSystemError, match="no_such_system"):
        systems.system_class("no_such_system")
    with pytest.raises(ValueError, match="already registered"):
        systems.register("pendulum", "mechsim.systems.pendulum")
    with pytest.raises(ValueError, match="class's id"):
        systems.register("another_name", SpringParticle)
    with pytest.raises(ValueError, match="snake_case"):
        systems.register("Bad Name", SpringParticle)
    with pytest.raises(TypeError):
        systems.register("not_a_model", object)  # type: ignore[arg-type]
    assert "another_name" not in systems.system_ids()


def test_registered_system_simulates_like_its_closed_form(spring_particle: None) -> None:
    assert "test_spring_particle" in mechsim.system_ids()
    model = mechsim.load_system("test_spring_particle")
    assert [law.key for law in model.laws()] == [
        "energy", "energy_function", "work_balance", "invariant:angular_momentum"]
    run = mechsim.simulate(model, 10.0, 0.01, tolerance=1e-12)
    x, z, vx, vz = closed_form(run.t)
    np.testing.assert_allclose(run.coordinate("x"), x, atol=1e-8)
    np.testing.assert_allclose(run.coordinate("z"), z, atol=1e-8)
    np.testing.assert_allclose(run.rate("z"), vz, atol=1e-8)
    e0 = 0.5 * M * (VX0**2 + VZ0**2) + 0.5 * K * (X0**2 + Z0**2) + M * G * Z0
    np.testing.assert_allclose(run.total, e0, rtol=0, atol=1e-10 * abs(e0))
    np.testing.assert_allclose(run.kinetic, 0.5 * M * (vx**2 + vz**2), atol=1e-8)
    L0 = M * (X0 * VZ0 - (Z0 - Z_EQ) * VX0)
    np.testing.assert_allclose(run.invariants["angular_momentum"], L0, atol=1e-10)
    frames = run.outputs.frames
    assert frames is not None
    np.testing.assert_allclose(frames[:, 0, 0], x, atol=1e-8)
    np.testing.assert_allclose(frames[:, 0, 2], z, atol=1e-8)


class Capture:
    capabilities = Capabilities()

    def __init__(self) -> None:
        self.messages: list[tuple[str, Any]] = []

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        self.messages.append((topic, msg))


def test_registered_system_runs_through_the_node_graph(spring_particle: None,
                                                       ros_context: Any) -> None:
    """Its default scene through the simulator and diagnostics nodes: every declared law OK,
    /tf poses the particle where the closed form puts it at each stamp."""
    from mechsim.outputs.messages import DEFAULT_TIME_OFFSET
    from mechsim.ros.launch import run_scene
    from mechsim.scene import single_system_scene

    cap = Capture()
    run = run_scene(single_system_scene("test_spring_particle"), fast=True, duration=3.0,
                    context=ros_context, sinks=[cap])
    assert not run.failures
    levels = {law: level for _, law, _, level in run.summary}
    assert levels == {"energy": 0, "energy_function": 0, "work_balance": 0,
                      "invariant:angular_momentum": 0}
    poses = [(tr.header.stamp, tr.transform.translation) for topic, m in cap.messages
             if topic == "/tf" for tr in m.transforms
             if tr.child_frame_id == "test_spring_particle/particle"]
    assert len(poses) == 301
    t = np.array([s.sec + 1e-9 * s.nanosec - DEFAULT_TIME_OFFSET for s, _ in poses])
    x, z, _, _ = closed_form(t)
    np.testing.assert_allclose([p.x for _, p in poses], x, atol=1e-6)
    np.testing.assert_allclose([p.z for _, p in poses], z, atol=1e-6)


def test_initial_conditions_follow_one_rule() -> None:
    """The README's rule: everything that sets the initial state is `initial.<name>` or
    `initial_rate.<name>` (no `initial_speed`-style names)."""
    from mechsim.systems import system_class, system_ids

    bad = [f"{sid}: {p.name}" for sid in system_ids()
           for p in system_class(sid).parameter_spec()
           if p.name.startswith("initial") and not p.name.startswith(("initial.",
                                                                       "initial_rate."))]
    assert not bad, bad
