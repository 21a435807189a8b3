"""Jacobi's elliptic functions and the elliptic integrals F and Π (``systems._elliptic``)
against mpmath and scipy, near the separatrix (m → 1, given by its complement) too."""

from __future__ import annotations

import numpy as np
import pytest

import mechsim.systems._elliptic as el


def test_jacobi_functions_against_mpmath() -> None:
    """sn, cn, dn and F(φ | m) from (m, 1 − m), near the separatrix too, against mpmath."""
    mpmath = pytest.importorskip("mpmath")
    mpmath.mp.dps = 40
    u = np.array([0.3, 2.0, 7.5, 40.0])
    for m1 in (1.0, 0.7, 0.1, 1.9e-5, 1e-12):
        m = mpmath.mpf(1) - mpmath.mpf(m1)
        sn, cn, dn = el.jacobi_elliptic(u, float(m), m1)
        for name, got in (("sn", sn), ("cn", cn), ("dn", dn)):
            ref = np.array([float(mpmath.ellipfun(name, x, m=m)) for x in u])
            assert np.max(np.abs(got - ref)) < 3e-14, (name, m1)
        for phi in (0.2, 1.4, -2.5, 3.0):
            assert el.elliptic_f(phi, m1) == pytest.approx(float(mpmath.ellipf(phi, m)),
                                                           rel=1e-14, abs=1e-15)
    for m1 in (0.77, 1e-9):  # dn at the quarter periods u = K, 3K: √m1, where cn = 0
        m = 1.0 - m1
        K = float(mpmath.ellipk(m))
        _, _, dn = el.jacobi_elliptic(np.array([K, 3 * K]), m, m1)
        assert np.allclose(dn, np.sqrt(m1), rtol=1e-12, atol=0.0), m1
    sn, cn, dn = el.jacobi_elliptic(u, 1.0, 0.0)  # on the separatrix: tanh, sech
    assert np.allclose(sn, np.tanh(u), rtol=1e-15) and np.allclose(cn, 1 / np.cosh(u))


def test_landen_sn_cn_dn_against_mpmath() -> None:
    """``sn_cn_dn`` (descending Landen, one sine and cosine a call) against mpmath, from the
    circle to the separatrix, at the quarter periods too (dn = √m1 where cn = 0)."""
    mpmath = pytest.importorskip("mpmath")
    mpmath.mp.dps = 40
    u = [0.3, -2.0, 7.5, 40.0]
    for m1 in (1.0, 0.77, 0.5, 0.1, 1.9e-5, 1e-12, 0.0):
        m = mpmath.mpf(1) - mpmath.mpf(m1)
        ratios, scale = el.agm_ratios(float(m), m1)
        a_n = scale * 0.5 ** ratios.size
        points = u if m1 == 0.0 else [*u, float(mpmath.ellipk(m)), 3 * float(mpmath.ellipk(m))]
        for x in points:
            got = el.sn_cn_dn(x, ratios, a_n, m1)
            for name, value in zip(("sn", "cn", "dn"), got, strict=True):
                ref = float(mpmath.ellipfun(name, x, m=m))
                assert abs(value - ref) < 3e-14 * max(1.0, abs(x)), (name, m1, x)
        if m1 > 0.0:  # dn at u = K: √m1 to its own precision
            K = float(mpmath.ellipk(m))
            assert el.sn_cn_dn(K, ratios, a_n, m1)[2] == pytest.approx(np.sqrt(m1), rel=1e-12)


def test_carlson_integrals_against_scipy() -> None:
    """R_F and R_J (joint duplication, p ≥ max(x, y, z)) against scipy's elliprf/elliprj."""
    from scipy.special import elliprf, elliprj

    rng = np.random.default_rng(7)
    for _ in range(3000):
        x, y, z = rng.random(3) * 10.0 ** rng.uniform(-4, 2, 3)
        if rng.random() < 0.2:
            x = 0.0
        p = max(x, y, z) * (1.0 + rng.random() * 10.0 ** rng.uniform(-8, 3))
        f, j = el.carlson_rf_rj(x, y, z, p)
        assert f == pytest.approx(float(elliprf(x, y, z)), rel=4e-15)
        assert el.carlson_rf(x, y, z) == pytest.approx(float(elliprf(x, y, z)), rel=4e-15)
        assert j == pytest.approx(float(elliprj(x, y, z, p)), rel=4e-15)


def test_elliptic_pi_against_mpmath() -> None:
    """Π(n; φ | m) for n ≤ 0, any φ (quasi-periodic beyond ±π/2), m near 1 from m1 too."""
    mpmath = pytest.importorskip("mpmath")
    mpmath.mp.dps = 40
    phis = np.array([0.3, 1.5, 2.0, -4.0, 20.0])
    for m1 in (1.0, 0.5, 1e-6, 1e-12):
        m = mpmath.mpf(1) - mpmath.mpf(m1)
        for n in (0.0, -0.3, -5.0, -1e3):
            got = el.elliptic_pi(n, phis, m1)
            ref = [mpmath.ellippi(n, mpmath.mpf(float(f)), m) for f in phis]
            for g, r in zip(got, ref, strict=True):
                assert g == pytest.approx(float(r), rel=1e-13), (n, m1)
