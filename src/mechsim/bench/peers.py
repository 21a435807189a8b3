"""Peers: the same IVP solved by scipy, hand-written numba loops, a matrix-exponential
propagator, REBOUND, MuJoCo and Drake, as their users would.

Each adapter turns a :class:`~mechsim.bench.problems.Problem` and one setting of its accuracy
knob into a zero-argument callable that integrates from the initial state and returns the
states ``[q, v]`` at the problem's sample times (plus counters). Building a model (MJCF
compile, Drake diagram) happens before the callable and is not timed; creating the simulation
object and stepping is.

- scipy: ``solve_ivp`` (RK45, DOP853, Radau, LSODA) with rtol = atol = setting, ``t_eval`` at
  the samples, on the plain numpy right-hand side of the problem (no Jacobian given).
- handwritten: what a competent user writes in an afternoon with numba: fixed-step RK4 on the
  problem's own right-hand side ``deriv`` (every problem), Yoshida-4 (the Forest–Ruth /
  Yoshida fourth-order composition of velocity Verlet, weights w₁, w₀, w₁ with
  w₁ = 1/(2 − 2^⅓), w₀ = −2^⅓ w₁; kick–drift–kick, the last force reused by the next stage)
  on ``accel`` where q̈ does not depend on q̇, and the Boris pusher (drift ½h, E half-kick,
  rotation about B, E half-kick, drift ½h) for the charged particle in its uniform fields.
  All allocation-free loops over in-place kernels, swept over steps per period (setting).
  Each loop and kernel is JIT-compiled once, in ``prepare``, by a run on the first two
  samples: the timed callable never includes compilation.
- expm (linear problems: the harmonic and coupled oscillators): one matrix exponential
  ``scipy.linalg.expm(A Δt)`` for the sample interval (timed), then one matrix-vector product
  per sample; exact up to round-off, no accuracy knob (one point).
- rebound (kepler, cr3bp): IAS15 with ``epsilon`` = setting; WHFast with a fixed step (setting =
  steps per period: the orbit for kepler, the primaries' for cr3bp). The test particle has
  mass 0; kepler: around a unit mass, states relative to it; cr3bp: the two primaries on
  their circular orbit about the barycentre (at rest at the origin) are integrated too,
  states barycentric.
- mujoco (pendulum, double_pendulum): hinge joints, point masses (inertia 1e-15 kg m² about
  their centres; the double pendulum's second body hangs from the first at l₁, its hinge angle
  is relative, converted to and from the absolute θ₂), RK4 and semi-implicit Euler with a
  fixed step (setting = steps per second).
- drake (pendulum, double_pendulum): continuous MultibodyPlant (revolute joints, point masses;
  the second joint's parent frame is fixed to the first body at l₁, its angle relative),
  Simulator with the error-controlled runge_kutta3, runge_kutta5 and radau3 schemes,
  accuracy = setting.

A family whose package cannot be imported is reported missing (one line) and skipped.
``--quick`` runs only the local, cheap families (``QUICK_FAMILIES``).
"""

from __future__ import annotations

import functools
import importlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import SimpleNamespace
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
    settings: Sequence[float]
    prepare: Callable[[Problem, float], Runner]
    # Maps the runner's states to the problem's compared states (not timed); None: the runner
    # returns problem states.
    convert: Callable[[Problem, np.ndarray], np.ndarray] | None = None
    # What the runner returns -> (its states, its counters), after the timing; None: the
    # runner returns them.
    unpack: Callable[[Any, dict[str, Any]], tuple[np.ndarray, dict[str, Any]]] | None = None


def available(family: str) -> tuple[bool, str]:
    """Can the family's package be imported? (reason when not)."""
    module = {"scipy": "scipy.integrate", "rebound": "rebound", "mujoco": "mujoco",
              "drake": "pydrake.all", "handwritten": "numba", "expm": "scipy.linalg"}[family]
    try:
        mod = importlib.import_module(module)
    except Exception as e:  # noqa: BLE001 - any import failure means "missing"
        return False, f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"
    dist = {"handwritten": "numba", "expm": "scipy"}.get(family, family)
    if family in ("handwritten", "expm"):
        mod = importlib.import_module(dist)
    return True, str(getattr(mod, "__version__", "") or _dist_version(dist))


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

        cfg = pb.extra["rebound"]
        t = pb.times()
        k, origin = len(cfg["bodies"]), cfg["origin"]

        def run() -> tuple[np.ndarray, dict[str, Any]]:
            sim = rebound.Simulation()
            sim.G = cfg["G"]
            for m, x, y, vx, vy in cfg["bodies"]:
                sim.add(m=m, x=x, y=y, vx=vx, vy=vy)
            sim.add(m=0.0, x=pb.y0[0], y=pb.y0[1], vx=pb.y0[2], vy=pb.y0[3])
            sim.integrator = integrator
            out = np.empty((t.size, 4))
            ps = sim.particles

            def record(i: int) -> None:
                p = ps[k]
                if origin is None:
                    out[i] = (p.x, p.y, p.vx, p.vy)
                else:
                    c = ps[origin]
                    out[i] = (p.x - c.x, p.y - c.y, p.vx - c.vx, p.vy - c.vy)

            if integrator == "ias15":
                try:  # REBOUND 5; REBOUND 4 keeps it in ri_ias15
                    sim.integrator.epsilon = setting
                except AttributeError:
                    sim.ri_ias15.epsilon = setting
                for i, ti in enumerate(t):
                    if ti > 0:
                        sim.integrate(float(ti))
                    record(i)
            else:  # whfast: fixed step, a whole number of steps per sample interval
                gap = t[1] - t[0]
                n_sub = max(1, math.ceil(gap / (cfg["period"] / setting) - 1e-9))
                sim.dt = gap / n_sub
                record(0)
                for i in range(1, t.size):
                    sim.steps(n_sub)
                    record(i)
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


# --- hand-written numba loops ----------------------------------------------------------------
@functools.cache
def _loops() -> SimpleNamespace:
    """The hand-written loops, compiled lazily (numba is imported on first use)."""
    return SimpleNamespace(rk4=_rk4_loop(), yoshida4=_yoshida4_loop(), boris=_boris_loop())


def _rk4_loop() -> Any:
    """Classic RK4 with n_sub steps per output interval, through the kernel ``f``."""
    from numba import njit

    @njit(cache=False)
    def rk4(f, p, y0, t_out, n_sub):  # type: ignore[no-untyped-def]
        n = y0.size
        Y = np.empty((t_out.size, n))
        y = y0.copy()
        k1, k2, k3, k4, tmp = (np.empty(n), np.empty(n), np.empty(n), np.empty(n),
                               np.empty(n))
        Y[0] = y
        for i in range(1, t_out.size):
            t = t_out[i - 1]
            h = (t_out[i] - t) / n_sub
            for _ in range(n_sub):
                f(t, y, p, k1)
                for j in range(n):
                    tmp[j] = y[j] + 0.5 * h * k1[j]
                f(t + 0.5 * h, tmp, p, k2)
                for j in range(n):
                    tmp[j] = y[j] + 0.5 * h * k2[j]
                f(t + 0.5 * h, tmp, p, k3)
                for j in range(n):
                    tmp[j] = y[j] + h * k3[j]
                f(t + h, tmp, p, k4)
                for j in range(n):
                    y[j] += h / 6.0 * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j])
                t += h
            Y[i] = y
        return Y
    return rk4


def _yoshida4_loop() -> Any:
    """Yoshida's 4th-order composition of velocity Verlet on the acceleration ``acc``."""
    from numba import njit

    @njit(cache=False)
    def yoshida4(acc, p, y0, t_out, n_sub):  # type: ignore[no-untyped-def]
        n = y0.size // 2
        q, v, a = y0[:n].copy(), y0[n:].copy(), np.empty(n)
        w1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
        w0 = 1.0 - 2.0 * w1
        Y = np.empty((t_out.size, 2 * n))
        Y[0] = y0
        t = t_out[0]
        acc(t, q, p, a)
        for i in range(1, t_out.size):
            h = (t_out[i] - t_out[i - 1]) / n_sub
            for _ in range(n_sub):
                for stage in range(3):
                    hw = h * (w0 if stage == 1 else w1)
                    for j in range(n):
                        v[j] += 0.5 * hw * a[j]
                        q[j] += hw * v[j]
                    t += hw
                    acc(t, q, p, a)
                    for j in range(n):
                        v[j] += 0.5 * hw * a[j]
            t = t_out[i]
            Y[i, :n] = q
            Y[i, n:] = v
        return Y
    return yoshida4


def _boris_loop() -> Any:
    """Boris's push for uniform E and B fields."""
    from numba import njit

    @njit(cache=False)
    def boris(qm, E, B, y0, t_out, n_sub):  # type: ignore[no-untyped-def]
        x, v = y0[:3].copy(), y0[3:].copy()
        vm, vp, tv, sv = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
        Y = np.empty((t_out.size, 6))
        Y[0] = y0
        for i in range(1, t_out.size):
            h = (t_out[i] - t_out[i - 1]) / n_sub
            for j in range(3):  # rotation vectors of the (uniform) magnetic field
                tv[j] = 0.5 * h * qm * B[j]
            t2 = tv[0] * tv[0] + tv[1] * tv[1] + tv[2] * tv[2]
            for j in range(3):
                sv[j] = 2.0 * tv[j] / (1.0 + t2)
            for _ in range(n_sub):
                for j in range(3):
                    x[j] += 0.5 * h * v[j]
                    vm[j] = v[j] + 0.5 * h * qm * E[j]
                vp[0] = vm[0] + vm[1] * tv[2] - vm[2] * tv[1]
                vp[1] = vm[1] + vm[2] * tv[0] - vm[0] * tv[2]
                vp[2] = vm[2] + vm[0] * tv[1] - vm[1] * tv[0]
                v[0] = vm[0] + vp[1] * sv[2] - vp[2] * sv[1] + 0.5 * h * qm * E[0]
                v[1] = vm[1] + vp[2] * sv[0] - vp[0] * sv[2] + 0.5 * h * qm * E[1]
                v[2] = vm[2] + vp[0] * sv[1] - vp[1] * sv[0] + 0.5 * h * qm * E[2]
                for j in range(3):
                    x[j] += 0.5 * h * v[j]
            Y[i, :3] = x
            Y[i, 3:] = v
        return Y
    return boris


_JIT: dict[Any, Any] = {}


def _jit(f: Any) -> Any:
    """One numba dispatcher per problem kernel (compiled on its first call)."""
    if f not in _JIT:
        from numba import njit

        _JIT[f] = njit(cache=False)(f)
    return _JIT[f]


def _n_sub(pb: Problem, steps_per_period: float) -> int:
    t = pb.times()
    return max(1, math.ceil(steps_per_period * (t[1] - t[0]) / pb.period - 1e-9))


def _handwritten(method: str) -> Callable[[Problem, float], Runner]:
    def prepare(pb: Problem, steps_per_period: float) -> Runner:
        loops = _loops()
        t = pb.times()
        n_sub = _n_sub(pb, steps_per_period)
        y0 = np.ascontiguousarray(pb.y0, dtype=np.float64)
        steps = n_sub * (t.size - 1)
        if method == "boris":
            b = pb.extra["boris"]
            E, B = np.array(b["E"], dtype=np.float64), np.array(b["B"], dtype=np.float64)
            qm = float(b["q_over_m"])

            def call(tt: np.ndarray) -> np.ndarray:
                return loops.boris(qm, E, B, y0, tt, n_sub)  # type: ignore[no-any-return]
            evals = None
        else:
            loop = loops.rk4 if method == "rk4" else loops.yoshida4
            kernel = _jit(pb.deriv if method == "rk4" else pb.accel)
            p = np.ascontiguousarray(pb.p, dtype=np.float64)

            def call(tt: np.ndarray) -> np.ndarray:
                return loop(kernel, p, y0, tt, n_sub)  # type: ignore[no-any-return]
            evals = 4 * steps if method == "rk4" else 3 * steps + 1
        call(t[:2].copy())  # JIT-compile now, outside the timed callable

        def run() -> tuple[np.ndarray, dict[str, Any]]:
            return call(t), {"n_steps": steps, "n_rhs": evals}
        return run
    return prepare


# --- matrix exponential ---------------------------------------------------------------------
def _expm(pb: Problem, setting: float) -> Runner:
    from scipy.linalg import expm

    if pb.linear is None:
        raise ValueError(f"{pb.name} is not linear")
    A = np.asarray(pb.linear, dtype=np.float64)
    t = pb.times()
    gap = float(t[1] - t[0])

    def run() -> tuple[np.ndarray, dict[str, Any]]:
        P = expm(A * gap)
        Y = np.empty((t.size, pb.y0.size))
        Y[0] = pb.y0
        for i in range(1, t.size):
            Y[i] = P @ Y[i - 1]
        return Y, {"n_steps": t.size - 1, "n_rhs": None}
    return run


QUICK_FAMILIES = ("scipy", "handwritten", "expm")  # --quick: local, cheap peers only
STEPS_PER_PERIOD = [4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096, 8192, 16384]


def contestants(pb: Problem, quick: bool, families: tuple[str, ...] | None = None
                ) -> tuple[list[Contestant], dict[str, str], dict[str, str]]:
    """Peer contestants for ``pb`` (only families it fits; with ``quick`` only
    ``QUICK_FAMILIES``); also the families missing (with reason) and the versions of those
    found."""
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
        if quick and fam not in QUICK_FAMILIES:  # found, but --quick runs only local peers
            continue
        if fam == "scipy":
            for m in ("RK45", "DOP853", "Radau", "LSODA"):
                out.append(Contestant(f"scipy:{m}", fam, "rtol=atol", tols, _scipy(m)))
        elif fam == "handwritten":
            spp = [8, 32, 128] if quick else STEPS_PER_PERIOD
            out.append(Contestant("handwritten:RK4", fam, "steps_per_period", spp,
                                  _handwritten("rk4")))
            if pb.accel is not None:
                out.append(Contestant("handwritten:Yoshida4", fam, "steps_per_period", spp,
                                      _handwritten("yoshida4")))
            if "boris" in pb.extra:
                out.append(Contestant("handwritten:Boris", fam, "steps_per_period", spp,
                                      _handwritten("boris")))
        elif fam == "expm":
            out.append(Contestant("expm:propagator", fam, "none", [0.0], _expm))
        elif fam == "rebound":
            out.append(Contestant("rebound:IAS15", fam, "epsilon",
                                  [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10],
                                  _rebound("ias15")))
            out.append(Contestant("rebound:WHFast", fam, "steps_per_period",
                                  [10, 30, 100, 300, 1000, 3000, 10000], _rebound("whfast")))
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
