"""The scattering beam (PHYS0500 §5.3, the cross-section experiment): many trajectories of the
``scattering`` system through the stepper, histogrammed into dσ/dΩ. An experiment run on a
system, so it lives above the physics and stepping layers and imports both downward."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import quad

from mechsim.ensemble import simulate_many
from mechsim.errors import ParameterError
from mechsim.systems._scattering import lab_cross_section
from mechsim.systems.scattering import Scattering


@dataclass
class Beam:
    """Trajectories of a beam and the cross-sections they give. The beam is cut into ``count``
    rings b_i < b < b_i+1 of area dσ = π(b_i+1² − b_i²); one trajectory runs at each ring edge
    b_i and each ring's dσ is spread evenly over the solid angle between its edges'
    deflections.
    Angles in rad, σ in m²/sr; ``*_measured`` = dσ in a bin / the bin's solid angle,
    ``*_analytic`` = the analytic σ averaged over the bin."""

    impact_parameters: np.ndarray  # ring edges b_i (count + 1 trajectories)
    weights: np.ndarray  # dσ of each ring (count)
    cm_angles: np.ndarray  # measured θ at each b_i
    lab_angles: np.ndarray  # measured ψ at each b_i
    cm_edges: np.ndarray
    cm_measured: np.ndarray
    cm_analytic: np.ndarray
    lab_edges: np.ndarray
    lab_measured: np.ndarray
    lab_analytic: np.ndarray
    wall_time: float

    @property
    def total_cross_section(self) -> float:
        return float(np.sum(self.weights))


def _bin_average(f, edges: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    """∫ f dΩ / ΔΩ over each bin [θ_j, θ_j+1], dΩ = 2π sin θ dθ."""
    out = np.empty(edges.size - 1)
    for j in range(out.size):
        lo, hi = float(edges[j]), float(edges[j + 1])
        val, _ = quad(lambda t: float(f(t)) * math.sin(t), lo, hi, limit=200)
        out[j] = val / (math.cos(lo) - math.cos(hi))
    return out


def _histogram(angles: np.ndarray, weights: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """dσ/dΩ per bin: ring i's dσ spread evenly over the solid angle between its edges'
    deflections angle_i and angle_i+1 (either order), i.e. linearly in cos(angle)."""
    c, ce = -np.cos(angles), -np.cos(edges)
    lo = np.minimum(c[:-1], c[1:])[:, None]
    hi = np.maximum(c[:-1], c[1:])[:, None]
    width = np.maximum(hi - lo, 1e-300)
    below = np.clip((ce[None, :] - lo) / width, 0.0, 1.0)  # fraction of ring below the edge
    below = np.where(hi - lo > 0, below, (ce[None, :] >= lo).astype(float))
    return (weights @ np.diff(below, axis=1)) / (2 * np.pi * np.diff(ce))


def beam(model: Scattering, count: int = 2000, bins: int = 20,
         b_range: tuple[float, float] | None = None, spacing: str | None = None,
         tolerance: float = 1e-10) -> Beam:
    """Run a beam of ``count`` rings of impact parameter in ``b_range`` (default: [0, a] for the
    hard sphere; the b of θ = 170° … 10° for the Coulomb centre), one trajectory per ring edge,
    all through DOP853 in one ensemble (``simulate_many``, over the cores) from
    |r| = ``initial.distance`` until the
    projectile is beyond 1.2 × that distance again, and histogram dσ = 2πb db over the
    measured CM angle θ (direction of the final ṙ) and LAB angle ψ (of the final v₁ = V +
    (m₂/M)ṙ, with |ṙ| brought to its value at infinity by energy conservation for the Coulomb
    centre: at r = 1000 k/E the speed still lacks ~k/(2Er) ~ 5·10⁻⁴, which would shift ψ) in
    ``bins`` equal bins spanning the measured range. ``spacing``: "area" (equal dσ per ring,
    default for the hard sphere) or "log" (geometric ring edges, default for Rutherford's
    steep σ)."""
    import time

    start = time.perf_counter()
    coulomb = model.target == "coulomb"
    if b_range is None:
        b_range = ((model.impact_parameter_of(math.radians(170)),
                    model.impact_parameter_of(math.radians(10))) if coulomb
                   else (0.0, model.value("sphere_radius")))
    spacing = spacing or ("log" if coulomb else "area")
    if spacing not in ("log", "area"):
        raise ParameterError("spacing", f"must be log or area (got {spacing!r})")
    b_lo, b_hi = b_range
    bs = (np.geomspace(b_lo, b_hi, count + 1) if spacing == "log"
          else np.sqrt(np.linspace(b_lo**2, b_hi**2, count + 1)))
    weights = np.pi * np.diff(bs**2)
    m1, m2 = model.value("mass_1"), model.value("mass_2")
    M = m1 + m2
    u, D = model.speed(), model.value("initial.distance")
    k, mu = model.force_constant(), model.reduced_mass()
    scale = model.force_constant() / model.cm_energy() if coulomb \
        else model.value("sphere_radius")
    t_end = (2.2 * D + 20.0 * scale) / u
    theta, psi = np.empty(bs.size), np.empty(bs.size)
    starts = np.array([np.concatenate(model.state_for(float(b))) for b in bs])
    run = simulate_many(model, t_end, t_end, states=starts, tolerance=tolerance,
                        method="dop853", outputs=(), work_terms=False)
    ends = np.concatenate([run.q[:, -1], run.v[:, -1]], axis=1)
    for i, b in enumerate(bs):
        y = ends[i]
        if float(np.hypot(y[2], y[3])) < 1.2 * D:
            raise RuntimeError(f"scattering beam: trajectory b = {b:g} did not get away")
        V, w = y[4:6], y[6:8]
        if coulomb:  # the speed still to regain from k/r (energy conservation); not the angle
            w = w * math.sqrt(1.0 + 2.0 * k / (mu * float(np.hypot(y[2], y[3])) * (w @ w)))
        v1 = V + m2 / M * w
        theta[i] = math.atan2(abs(w[1]), w[0])
        psi[i] = math.atan2(abs(v1[1]), v1[0])
    cm_edges = np.linspace(theta.min(), theta.max(), bins + 1)
    lab_edges = np.linspace(psi.min(), psi.max(), bins + 1)
    lo, hi = float(theta.min()), float(theta.max())

    def sigma_cm(t: float) -> float:  # the analytic σ(θ) over the θ range the beam covers
        return float(model.cross_section(t)) if lo <= t <= hi else 0.0

    x = model.mass_ratio()
    return Beam(
        impact_parameters=bs, weights=weights, cm_angles=theta, lab_angles=psi,
        cm_edges=cm_edges, cm_measured=_histogram(theta, weights, cm_edges),
        cm_analytic=_bin_average(sigma_cm, cm_edges),
        lab_edges=lab_edges, lab_measured=_histogram(psi, weights, lab_edges),
        lab_analytic=_bin_average(lambda p: lab_cross_section(sigma_cm, p, x)[0], lab_edges),
        wall_time=time.perf_counter() - start)
