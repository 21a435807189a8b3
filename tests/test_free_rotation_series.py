"""The torque-free rigid body's closed form evaluated through Fourier series over the period
(``_free_rotation._period_series``) against the same motion evaluated term by term (Landen's
descending recursion for am u and Carlson's R_F, R_J for Π(−N; am u)): two independent
evaluations of dn u, am u and Π(−N; am u)."""

from __future__ import annotations

import numpy as np
import pytest

from mechsim.systems import _free_rotation
from mechsim.systems._elliptic import am_dn, third_kind

BODIES = [((1.0, 2.0, 3.0), (3.0, 1.0, 2.0)),
          ((1.0, 2.0, 3.0), (0.3, -2.0, 0.5)),
          ((3.0, 2.0, 1.0), (-0.7, 1.1, 0.4)),
          ((0.0041666666666666675, 0.008333333333333333, 0.010833333333333334),
           (0.02, 4.0, 0.02)),  # close to the intermediate axis: 68 terms
          ((1.0, 1.5, 1.6), (1.7, 0.75, -0.77))]


def _term_by_term(motion: _free_rotation.EllipticMotion) -> _free_rotation.EllipticMotion:
    c = motion.consts.copy()
    am0, _ = am_dn(c[1], motion.ratios, c[2], c[3])
    c[6] = third_kind(-c[4], am0, c[3], c[5])
    return motion._replace(consts=c, coefs=np.empty((3, 0)), terms=np.zeros(3, dtype=np.int64))


@pytest.mark.parametrize("moments, omega", BODIES)
def test_series_agree_with_term_by_term(moments: tuple, omega: tuple) -> None:
    rng = np.random.default_rng(7)
    q0 = rng.normal(size=4)
    q0 /= np.linalg.norm(q0)
    motion = _free_rotation.free_motion(moments, q0, np.array(omega))
    assert isinstance(motion, _free_rotation.EllipticMotion)
    assert motion.coefs.shape[1] > 0  # the series are used
    t = np.sort(rng.uniform(0.0, 100.0, 300))
    rows, W = _free_rotation.free_rotation_at(motion, t)
    rows2, W2 = _free_rotation.free_rotation_at(_term_by_term(motion), t)
    assert np.max(np.abs(W - W2)) < 1e-12 * np.max(np.abs(W2))
    assert np.max(np.abs(rows[:, :4] - rows2[:, :4])) < 1e-11
    assert np.max(np.abs(rows[:, 4:] - rows2[:, 4:])) < 1e-11 * np.max(np.abs(rows2[:, 4:]))


def test_near_the_separatrix_term_by_term() -> None:
    """Where a period needs more than SERIES_MAX_SAMPLES samples, no series are made."""
    motion = _free_rotation.free_motion((1.0, 2.0, 3.0), np.array([0.0, 0.0, 0.0, 1.0]),
                                np.array([1e-9, 1.0, 1e-9]))
    assert isinstance(motion, _free_rotation.EllipticMotion)
    assert motion.coefs.shape[1] == 0
