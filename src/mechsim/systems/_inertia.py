"""Inertia tensors (PHYS0500 – Advanced Classical Mechanics, §7.2–7.5): standard solids about
their centroid, point masses, the general parallel-axis theorem J_ij = I_ij + M(a² δ_ij − a_i a_j)
(§7.5; the notes' index typos corrected), composition of parts, principal axes (§7.4). Plain
numpy, used by ``rigid_body`` to build its bodies."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def box_inertia(mass: float, size: tuple[float, float, float]) -> np.ndarray:
    """Solid box with edge lengths (a, b, c) along x, y, z, about its centre:
    (M/12) diag(b² + c², a² + c², a² + b²)."""
    a, b, c = size
    return mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])


def cylinder_inertia(mass: float, radius: float, length: float) -> np.ndarray:
    """Solid circular cylinder along z about its centre: diag(M(3r² + L²)/12, same, Mr²/2)."""
    t = mass * (3 * radius**2 + length**2) / 12.0
    return np.diag([t, t, 0.5 * mass * radius**2])


def sphere_inertia(mass: float, radius: float) -> np.ndarray:
    """Solid sphere about its centre: (2/5) M r² 1."""
    return 0.4 * mass * radius**2 * np.eye(3)


def point_mass_inertia(mass: float, position: np.ndarray) -> np.ndarray:
    """A point mass at ``position``, about the origin: m (r² 1 − r rᵀ) (eq. 7.1)."""
    r = np.asarray(position, dtype=float)
    return mass * (r @ r * np.eye(3) - np.outer(r, r))


def parallel_axis(inertia_cm: np.ndarray, mass: float, offset: np.ndarray) -> np.ndarray:
    """Tensor about a point Q from the one about the centre of mass, ``offset`` = a = CM − Q:
    J = I + M (a² 1 − a aᵀ) (PHYS0500 §7.5, line 1686)."""
    return np.asarray(inertia_cm, dtype=float) + point_mass_inertia(mass, offset)


@dataclass(frozen=True)
class Part:
    """A solid of mass ``mass`` with tensor ``inertia`` about its own centre, placed at
    ``position`` with orientation ``rotation`` (its axes in the body frame, as columns)."""

    mass: float
    inertia: np.ndarray
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: np.ndarray | None = None


def composite(parts: list[Part]) -> tuple[float, np.ndarray, np.ndarray]:
    """Total mass, centre of mass and inertia tensor about the centre of mass of ``parts``."""
    total = float(sum(p.mass for p in parts))
    cm = np.sum([p.mass * np.asarray(p.position, dtype=float) for p in parts], axis=0) / total
    inertia = np.zeros((3, 3))
    for p in parts:
        R = np.eye(3) if p.rotation is None else np.asarray(p.rotation, dtype=float)
        inertia += parallel_axis(R @ p.inertia @ R.T, p.mass, np.asarray(p.position) - cm)
    return total, cm, inertia


def principal_axes(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments and axes: I = Q diag(moments) Qᵀ, det Q = +1 (PHYS0500 §7.4).

    The axes are matched to the body axes they lie closest to (so a tensor that is already
    diagonal keeps its axes and their order) and point along their positive directions.
    """
    inertia = np.asarray(inertia, dtype=float)
    scale = float(np.trace(inertia)) or 1.0
    off = inertia - np.diag(np.diag(inertia))
    if np.max(np.abs(off)) <= 1e-14 * scale:
        return np.diag(inertia).copy(), np.eye(3)
    moments, Q = np.linalg.eigh(inertia)
    order = [-1, -1, -1]
    free = [0, 1, 2]
    # greedy: the eigenvector most aligned with a body axis takes that axis first
    pairs = sorted(((abs(Q[axis, k]), axis, k) for axis in range(3) for k in range(3)),
                   reverse=True)
    taken: set[int] = set()
    for _, axis, k in pairs:
        if order[axis] < 0 and k not in taken:
            order[axis] = k
            taken.add(k)
            free.remove(axis)
    Q = Q[:, order]
    moments = moments[order]
    for axis in range(3):
        if Q[axis, axis] < 0:
            Q[:, axis] = -Q[:, axis]
    if np.linalg.det(Q) < 0:
        Q[:, 2] = -Q[:, 2]
    return moments, Q
