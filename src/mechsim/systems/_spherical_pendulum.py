"""Shared physics of a point mass on a sphere of radius l about a fixed pivot (Lecture 10, spherical
pendulum (eqs. 10.47–10.50)): the spherical pendulum and the pendulum whose plane is forced to turn
(rotating hoop).

θ is the polar angle from straight down, φ the azimuth about +z (REP-103: z up), so the bob is
at l (sin θ cos φ, sin θ sin φ, −cos θ) and V = −m g l cos θ (zero at pivot height, as the
document's L = ½ m l²(θ̇² + sin²θ φ̇²) + m g l cos θ, eq. 10.47).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from mechsim.systems._symbolic import sympy as sp

if TYPE_CHECKING:
    from sympy import Expr


def kinetic(m: Expr, l: Expr, th: Expr, dth: Expr, dphi: Expr) -> Expr:
    """T = ½ m l² (θ̇² + sin²θ φ̇²)."""
    return m * l**2 * (dth**2 + sp.sin(th) ** 2 * dphi**2) / 2


def potential(m: Expr, l: Expr, g: Expr, th: Expr) -> Expr:
    """V = −m g l cos θ."""
    return -m * g * l * sp.cos(th)


def azimuthal_momentum(m: Expr, l: Expr, th: Expr, dphi: Expr) -> Expr:
    """p_φ = m l² sin²θ φ̇ (angular momentum about the vertical)."""
    return m * l**2 * sp.sin(th) ** 2 * dphi


def bob(l: Expr, th: Expr, phi: Expr) -> tuple[Expr, Expr, Expr]:
    """Bob position relative to the pivot."""
    return (l * sp.sin(th) * sp.cos(phi), l * sp.sin(th) * sp.sin(phi), -l * sp.cos(th))
