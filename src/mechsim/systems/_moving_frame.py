"""The astrodynamics moving frames VBN and RIC: their conventions, their angular velocities in
closed form, and the outputs every system that publishes them declares (``moving_frames`` on a
prescribed curve, ``orbit_frames`` on a dynamical orbit).

Source: “Minimal Frames” (the VBN and RIC definitions, the moving-frame matrix and the
minimality proofs) and “Moving Frames and the Twisted Cubic” (the derivatives of each axis and
the mapping to the angular velocity).

Axes (rows e₁, e₂, e₃; every frame published right-handed):
- ``vbn``: V̂ = v/|v|, N̂ = r×v/|r×v| (the orbit normal), B̂ = V̂×N̂. The documents name it
  "VBN", but the literal order (V̂, B̂, N̂) is left-handed (V̂×B̂ = −N̂): it is published in
  the right-handed order x = V̂, y = N̂, z = B̂, so the documents' (V, B, N) components are
  our (x, z, y).
- ``ric``: R̂ = r/|r|, Ĉ = r×v/|r×v|, Î = Ĉ×R̂ (x, y, z as given).

Angular velocity: ω is that of the frame relative to ``world`` in the usual sense
ė_i = ω × e_i, published as its components along the frame's own axes. The moving-frame
matrix (ė₁; ė₂; ė₃) = [[0, α, β], [−α, 0, γ], [−β, −γ, 0]] (e₁; e₂; e₃) then has α = ω₃,
β = −ω₂, γ = ω₁ (the document's mapping "α → −ω_z, β → ω_y, γ → −ω_x" describes −ω; the
magnitudes and minimality are the same). With L = r×v and its rate L̇ = r×a, the components
(``frame_rates``) are

    VBN: ω_x = N̂'·B̂ = (r×a)·B̂/|L|,  ω_y = −V̂'·B̂ = −a·B̂/|v|,  ω_z = V̂'·N̂ = a·N̂/|v|
    RIC: ω_x = −Î·Ĉ' = −(r×a)·Î/|L|, ω_y = −R̂'·Ĉ = −v·Ĉ/|r| ≡ 0, ω_z = R̂'·Î = v·Î/|r|

RIC is minimal on every path (ω_y ≡ 0: v ⟂ L). VBN is minimal exactly where the acceleration
stays in the instantaneous orbit plane, a·N̂ = 0: then (r×a)·B̂ = 0 too, N̂ is fixed and
ω = ω_y N̂. So for a central force (a ∥ r) VBN is minimal, as “Minimal Frames” says, but not
for the reason it gives ("a·v = 0": false on any eccentric orbit, and the term it is meant to
cancel, V̂'·B̂ ∝ (r·v)(v·a) − v²(a·r) = μ|L|²/r³ for a = −μr/r³, is the one component that is
not zero); the zero components are V̂'·N̂ ∝ v·(a×r) and N̂'·B̂, both zero because a ∥ r. A
drag or thrust along v, any force in the orbit plane, leaves VBN minimal; a force with a
component along N̂ (an oblate body's, ``orbit_frames``) makes all three components non-zero.
"""

from __future__ import annotations

from typing import Any

from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Quantity

#: Colours of the frames' axes visuals, one per frame.
FRAME_COLORS = {"vbn": (255, 170, 60), "ric": (120, 200, 120), "frenet": (120, 170, 255)}


def omega_quantities(frames: tuple[str, ...]) -> tuple[Quantity, ...]:
    """``<frame>_omega_x|y|z`` (ω along the frame's own axes), then ``<frame>_angular_speed``."""
    out = [Quantity(f"{f}_omega_{a}", "rad/s", f"{f.upper()} angular velocity along its "
                    f"{a} axis") for f in frames for a in "xyz"]
    out += [Quantity(f"{f}_angular_speed", "rad/s", f"|ω| of the {f.upper()} frame")
            for f in frames]
    return tuple(out)


def _dot(a: Any, b: Any) -> Any:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Any, b: Any) -> tuple[Any, Any, Any]:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def frame_rates(r: Any, v: Any, a: Any, sqrt: Any) -> dict[str, tuple[Any, Any, Any]]:
    """ω of VBN and RIC along their own axes (the formulas of the module docstring) from the
    position, velocity and acceleration: 3-sequences of numbers or sympy expressions, with the
    matching ``sqrt``. Defined where r×v ≠ 0."""
    L = _cross(r, v)
    Ldot = _cross(r, a)
    speed, radius, l2 = sqrt(_dot(v, v)), sqrt(_dot(r, r)), _dot(L, L)
    l = sqrt(l2)
    vxL = _cross(v, L)  # |v||L| B̂
    Lxr = _cross(L, r)  # |L||r| Î
    return {
        "vbn": (_dot(Ldot, vxL) / (speed * l2), -_dot(a, vxL) / (speed * speed * l),
                _dot(a, L) / (speed * l)),
        "ric": (-_dot(Lxr, Ldot) / (l2 * radius), -_dot(v, L) / (radius * l),
                _dot(v, Lxr) / (l * radius * radius)),
    }


def frame_axes(r: Any, v: Any) -> dict[str, tuple[Any, Any, Any]]:
    """The axes (rows: x, y, z, each a 3-tuple) of VBN and RIC from r and v (expressions)."""
    L = _cross(r, v)
    l, speed, radius = (sp.sqrt(_dot(w, w)) for w in (L, v, r))
    V = tuple(c / speed for c in v)
    N = tuple(c / l for c in L)
    R = tuple(c / radius for c in r)
    return {"vbn": (V, N, _cross(V, N)), "ric": (R, _cross(N, R), N)}


def quaternion_from_axes(e: tuple[Any, Any, Any]) -> tuple[Any, Any, Any, Any]:
    """Quaternion (x, y, z, w) of the frame whose unit axes (parent components) are the rows
    e[0..2], as sympy expressions: Shepperd's method (the pivot is the largest of w², x², y²,
    z², so no branch divides by a small number), the symbolic twin of
    ``_rotation.quat_from_rows``. R = eᵀ: R[i][j] = e[j][i]."""
    R = [[e[j][i] for j in range(3)] for i in range(3)]
    tr = R[0][0] + R[1][1] + R[2][2]
    branches = []
    s = 2 * sp.sqrt(1 + tr)
    branches.append(((R[2][1] - R[1][2]) / s, (R[0][2] - R[2][0]) / s, (R[1][0] - R[0][1]) / s,
                     s / 4))
    s = 2 * sp.sqrt(1 + R[0][0] - R[1][1] - R[2][2])
    branches.append((s / 4, (R[0][1] + R[1][0]) / s, (R[0][2] + R[2][0]) / s,
                     (R[2][1] - R[1][2]) / s))
    s = 2 * sp.sqrt(1 + R[1][1] - R[0][0] - R[2][2])
    branches.append(((R[0][1] + R[1][0]) / s, s / 4, (R[1][2] + R[2][1]) / s,
                     (R[0][2] - R[2][0]) / s))
    s = 2 * sp.sqrt(1 + R[2][2] - R[0][0] - R[1][1])
    branches.append(((R[0][2] + R[2][0]) / s, (R[1][2] + R[2][1]) / s, s / 4,
                     (R[1][0] - R[0][1]) / s))
    conditions = (sp.And(tr >= R[0][0], tr >= R[1][1], tr >= R[2][2]),
                  sp.And(R[0][0] >= R[1][1], R[0][0] >= R[2][2]), R[1][1] >= R[2][2], True)
    return tuple(sp.Piecewise(*((b[k], c) for b, c in zip(branches, conditions, strict=True)))
                 for k in range(4))  # type: ignore[return-value]
