"""Peers: the same IVP solved by scipy, REBOUND, MuJoCo and Drake, as their users would.

Each adapter turns a :class:`~mechsim.bench.problems.Problem` and one setting of its accuracy
knob into a zero-argument callable that integrates from the initial state and returns the
states ``[q, v]`` at the problem's sample times (plus counters). Building a model (MJCF
compile, Drake diagram) happens before the callable and is not timed; creating the simulation
object and stepping is.

- scipy: ``solve_ivp`` (RK45, DOP853, Radau, LSODA) with rtol = atol = setting, ``t_eval`` at
  the samples, on the plain numpy right-hand side of the problem (no Jacobian given).
- rebound (kepler): IAS15 with ``epsilon`` = setting; WHFast with a fixed step (setting = steps
  per orbit). A test particle of mass 0 around a unit mass, G = 1.
- mujoco (pendulum, double_pendulum): hinge joints, point masses (inertia 1e-15 kg m² about
  their centres; the double pendulum's second body hangs from the first at l₁, its hinge angle
  is relative, converted to and from the absolute θ₂), RK4 and semi-implicit Euler with a
  fixed step (setting = steps per second).
- drake (pendulum, double_pendulum): continuous MultibodyPlant (revolute joints, point masses;
  the second joint's parent frame is fixed to the first body at l₁, its angle relative),
  Simulator with the error-controlled runge_kutta3, runge_kutta5 and radau3 schemes,
  accuracy = setting.

A family whose package cannot be imported is reported missing (one line) and skipped.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from mechsim.bench.problems import Problem

Runner = Callable[[], tuple[np.ndarray, dict[str, Any]]]


@dataclass
class Contestant:
    """One method of one family, swept over ``settings`` of its accuracy knob."""

    name: str  # "family:method"
    family: str
    knob: str  # what the setting means: tolerance, epsilon, accuracy, steps_per_orbit, ...
    settings: list[float]
    prepare: Callable[[Problem, float], Runner]


def available(family: str) -> tuple[bool, str]:
    """Can the family's package be imported? (reason when not)."""
    module = {"scipy": "scipy.integrate", "rebound": "rebound", "mujoco": "mujoco",
              "drake": "pydrake.all"}[family]
    try:
        mod = importlib.import_module(module)
    except Exception as e:  # noqa: BLE001 - any import failure means "missing"
        return False, f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"
    return True, str(getattr(mod, "__version__", "") or _dist_version(family))


def _dist_version(family: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(family)
    except PackageNotFoundError:
        return "?"


def _tolerances(quick: bool, loosest: float = 1e-3, tightest: float = 1e-13) -> list[float]:
    if quick:
        return [1e-4, 1e-7, 1e-10]
    n = round(math.log10(loosest / tightest))
    return [loosest / 10**i for i in range(n + 1)]


# --- scipy ----------------------------------------------------------------------------------
def _scipy(method: str) -> Callable[[Problem, float], Runner]:
    def prepare(pb: Problem, tol: float) -> Runner:
        from scipy.integrate import solve_ivp

        t = pb.times()

        def run() -> tuple[np.ndarray, dict[str, Any]]:
            sol = solve_ivp(pb.rhs, (0.0, pb.t_end), pb.y0, method=method, t_eval=t,
                            rtol=tol, atol=tol)
            if not sol.success:
                raise RuntimeError(sol.message)
            return sol.y.T.copy(), {"n_rhs": int(sol.nfev), "n_steps": None}
        return run
    return prepare


# --- rebound --------------------------------------------------------------------------------
def _rebound(integrator: str) -> Callable[[Problem, float], Runner]:
    def prepare(pb: Problem, setting: float) -> Runner:
        import rebound

        t = pb.times()
        GM = float(pb.extra["GM"])
        period = pb.t_end / float(pb.extra["orbits"])

        def run() -> tuple[np.ndarray, dict[str, Any]]:
            sim = rebound.Simulation()
            sim.G = GM
            sim.add(m=1.0)
            sim.add(m=0.0, x=pb.y0[0], y=pb.y0[1], vx=pb.y0[2], vy=pb.y0[3])
            sim.integrator = integrator
            out = np.empty((t.size, 4))
            ps = sim.particles
            if integrator == "ias15":
                sim.integrator.epsilon = setting
                for i, ti in enumerate(t):
                    if ti > 0:
                        sim.integrate(float(ti))
                    out[i] = (ps[1].x - ps[0].x, ps[1].y - ps[0].y, ps[1].vx - ps[0].vx,
                              ps[1].vy - ps[0].vy)
            else:  # whfast: fixed step, a whole number of steps per sample interval
                gap = t[1] - t[0]
                k = max(1, math.ceil(gap / (period / setting) - 1e-9))
                sim.dt = gap / k
                done = 0
                for i, ti in enumerate(t):
                    n = round(ti / sim.dt) - done
                    if n > 0:
                        sim.steps(n)
                        done += n
                    out[i] = (ps[1].x - ps[0].x, ps[1].y - ps[0].y, ps[1].vx - ps[0].vx,
                              ps[1].vy - ps[0].vy)
            return out, {"n_steps": int(sim.steps_done), "n_rhs": None}
        return run
    return prepare


# --- mujoco ---------------------------------------------------------------------------------
def _pendulum_mjcf(pb: Problem, integrator: str) -> str:
    R, g, m = pb.extra["R"], pb.extra["g"], pb.extra["m"]
    return f"""<mujoco model="pendulum">
  <option gravity="0 0 {-g}" timestep="0.001" integrator="{integrator}"/>
  <worldbody>
    <body name="bob">
      <joint name="angle" type="hinge" axis="1 0 0" pos="0 0 0"/>
      <inertial pos="0 0 {-R}" mass="{m}" diaginertia="1e-15 1e-15 1e-15"/>
    </body>
  </worldbody>
</mujoco>"""


def _double_pendulum_mjcf(pb: Problem, integrator: str) -> str:
    x = pb.extra
    return f"""<mujoco model="double_pendulum">
  <option gravity="0 0 {-x['g']}" timestep="0.001" integrator="{integrator}"/>
  <worldbody>
    <body name="bob_1">
      <joint name="angle_1" type="hinge" axis="1 0 0" pos="0 0 0"/>
      <inertial pos="0 0 {-x['l1']}" mass="{x['m1']}" diaginertia="1e-15 1e-15 1e-15"/>
      <body name="bob_2" pos="0 0 {-x['l1']}">
        <joint name="angle_2" type="hinge" axis="1 0 0" pos="0 0 0"/>
        <inertial pos="0 0 {-x['l2']}" mass="{x['m2']}" diaginertia="1e-15 1e-15 1e-15"/>
      </body>
    </body>
  </worldbody>
</mujoco>"""


def _chain_to_joints(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Absolute angles/rates [q, v] of a planar chain -> joint (relative) positions, rates."""
    n = y.size // 2
    q, v = y[:n], y[n:]
    return np.diff(q, prepend=0.0), np.diff(v, prepend=0.0)


def _joints_to_chain(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.concatenate([np.cumsum(q), np.cumsum(v)])


_MJCF = {"pendulum": _pendulum_mjcf, "double_pendulum": _double_pendulum_mjcf}


def _mujoco(integrator: str) -> Callable[[Problem, float], Runner]:
    def prepare(pb: Problem, steps_per_second: float) -> Runner:
        import mujoco

        model = mujoco.MjModel.from_xml_string(_MJCF[pb.system](pb, integrator))
        t = pb.times()
        gap = t[1] - t[0]
        k = max(1, math.ceil(gap * steps_per_second - 1e-9))
        model.opt.timestep = gap / k

        def run() -> tuple[np.ndarray, dict[str, Any]]:
            data = mujoco.MjData(model)
            data.qpos[:], data.qvel[:] = _chain_to_joints(pb.y0)
            out = np.empty((t.size, pb.y0.size))
            out[0] = pb.y0
            for i in range(1, t.size):
                n = round((t[i] - t[i - 1]) / model.opt.timestep)
                mujoco.mj_step(model, data, nstep=n)
                out[i] = _joints_to_chain(data.qpos, data.qvel)
            return out, {"n_steps": round(t[-1] / model.opt.timestep), "n_rhs": None,
                         "dt": model.opt.timestep}
        return run
    return prepare


# --- drake ----------------------------------------------------------------------------------
def _drake(scheme: str) -> Callable[[Problem, float], Runner]:
    def prepare(pb: Problem, accuracy: float) -> Runner:
        from pydrake.all import (
            ApplySimulatorConfig,
            DiagramBuilder,
            FixedOffsetFrame,
            MultibodyPlant,
            RevoluteJoint,
            RigidTransform,
            RotationalInertia,
            Simulator,
            SimulatorConfig,
            SpatialInertia,
        )

        x = pb.extra
        # (mass, rod length) per link of the planar chain hanging from the origin.
        links = ([(x["m"], x["R"])] if pb.system == "pendulum"
                 else [(x["m1"], x["l1"]), (x["m2"], x["l2"])])
        builder = DiagramBuilder()
        plant = builder.AddSystem(MultibodyPlant(0.0))
        joints = []
        parent = plant.world_frame()
        for k, (m, R) in enumerate(links):
            body = plant.AddRigidBody(f"bob_{k + 1}", SpatialInertia.MakeFromCentralInertia(
                m, [0.0, 0.0, -R], RotationalInertia(0.0, 0.0, 0.0)))
            joints.append(plant.AddJoint(RevoluteJoint(f"angle_{k + 1}", parent,
                                                       body.body_frame(), [1.0, 0.0, 0.0])))
            parent = plant.AddFrame(FixedOffsetFrame(f"end_{k + 1}", body.body_frame(),
                                                     RigidTransform([0.0, 0.0, -R])))
        plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, -x["g"]])
        plant.Finalize()
        diagram = builder.Build()
        config = SimulatorConfig(integration_scheme=scheme, accuracy=accuracy,
                                 use_error_control=True, target_realtime_rate=0.0,
                                 publish_every_time_step=False)
        t = pb.times()

        def run() -> tuple[np.ndarray, dict[str, Any]]:
            sim = Simulator(diagram)
            ApplySimulatorConfig(config, sim)
            ctx = sim.get_mutable_context()
            pc = plant.GetMyMutableContextFromRoot(ctx)
            q0, v0 = _chain_to_joints(pb.y0)
            for j, qj, vj in zip(joints, q0, v0, strict=True):
                j.set_angle(pc, float(qj))
                j.set_angular_rate(pc, float(vj))
            sim.Initialize()
            out = np.empty((t.size, pb.y0.size))
            out[0] = pb.y0
            for i in range(1, t.size):
                sim.AdvanceTo(float(t[i]))
                out[i] = _joints_to_chain(np.array([j.get_angle(pc) for j in joints]),
                                          np.array([j.get_angular_rate(pc) for j in joints]))
            integ = sim.get_integrator()
            return out, {"n_steps": int(integ.get_num_steps_taken()),
                         "n_rhs": int(integ.get_num_derivative_evaluations())}
        return run
    return prepare


def contestants(pb: Problem, quick: bool, families: tuple[str, ...] | None = None
                ) -> tuple[list[Contestant], dict[str, str], dict[str, str]]:
    """Peer contestants for ``pb`` (only families it fits; scipy only when ``quick``); also
    the families missing (with reason) and the versions of those found."""
    wanted = [f for f in pb.peers if families is None or f in families]
    out: list[Contestant] = []
    missing: dict[str, str] = {}
    versions: dict[str, str] = {}
    tols = _tolerances(quick)
    for fam in wanted:
        ok, info = available(fam)
        if not ok:
            missing[fam] = info
            continue
        versions[fam] = info
        if quick and fam != "scipy":  # found, but --quick runs scipy only
            continue
        if fam == "scipy":
            for m in ("RK45", "DOP853", "Radau", "LSODA"):
                out.append(Contestant(f"scipy:{m}", fam, "rtol=atol", tols, _scipy(m)))
        elif fam == "rebound":
            out.append(Contestant("rebound:IAS15", fam, "epsilon",
                                  [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10],
                                  _rebound("ias15")))
            out.append(Contestant("rebound:WHFast", fam, "steps_per_orbit",
                                  [10, 30, 100, 300, 1000], _rebound("whfast")))
        elif fam == "mujoco":
            sps = [50, 100, 200, 500, 1000, 2000, 5000, 10000]
            out.append(Contestant("mujoco:RK4", fam, "steps_per_second", sps, _mujoco("RK4")))
            out.append(Contestant("mujoco:Euler", fam, "steps_per_second", sps,
                                  _mujoco("Euler")))
        elif fam == "drake":
            acc = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12]
            for scheme in ("runge_kutta3", "runge_kutta5", "radau3"):
                out.append(Contestant(f"drake:{scheme}", fam, "accuracy", acc, _drake(scheme)))
    return out, missing, versions
