"""Rotation helpers shared by the frame and rigid-body systems (not a system).

Every function here is written for numba: DirectModel systems list the ones they need in their
``kernel_functions`` and the source is pasted into their kernel module (so: plain functions,
scalars and float arrays only, ``math`` and ``np``, and each other). They run as plain Python
too, which is how the tests and the oracles call them.

Conventions: quaternions are (x, y, z, w) as in ROS, Hamilton product, unit norm; the rotation
R(q) of a frame's quaternion maps the frame's components to its parent's (v_parent = R v_child),
so the columns of R are the frame's axes in the parent and q̇ = ½ q ⊗ (ω_body, 0).
"""

from __future__ import annotations

import math


def quat_product(a, b):
    """a ⊗ b (Hamilton product, (x, y, z, w) storage) as a tuple; a, b arrays or tuples."""
    ax, ay, az, aw = a[0], a[1], a[2], a[3]
    bx, by, bz, bw = b[0], b[1], b[2], b[3]
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def rotate(q, v):
    """R(q) v for a unit quaternion q, as a tuple (no arrays made: kernel-safe)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    # t = 2 q_vec × v; v' = v + w t + q_vec × t
    tx = 2.0 * (y * v[2] - z * v[1])
    ty = 2.0 * (z * v[0] - x * v[2])
    tz = 2.0 * (x * v[1] - y * v[0])
    return (v[0] + w * tx + (y * tz - z * ty),
            v[1] + w * ty + (z * tx - x * tz),
            v[2] + w * tz + (x * ty - y * tx))


def rotate_inverse(q, v):
    """R(q)ᵀ v for a unit quaternion q, as a tuple: the rotation of the conjugate."""
    return rotate((-q[0], -q[1], -q[2], q[3]), v)


def quat_mul(a, b, out):
    """out = a ⊗ b; out may not alias a or b."""
    r = quat_product(a, b)
    for i in range(4):
        out[i] = r[i]


def quat_rotate(q, v, out):
    """out = R(q) v for a unit quaternion q (out may not alias v)."""
    r = rotate(q, v)
    for i in range(3):
        out[i] = r[i]


def quat_rotate_inverse(q, v, out):
    """out = R(q)ᵀ v for a unit quaternion q (out may not alias v)."""
    r = rotate_inverse(q, v)
    for i in range(3):
        out[i] = r[i]


def quat_from_rows(e, out):
    """Quaternion of the frame whose unit axes, in parent components, are the rows e[0..2].

    The rotation matrix is R = eᵀ (columns = axes). Shepperd's method: take the largest of
    w², x², y², z² as pivot, so the result is accurate for every rotation. The rows must be
    orthonormal and right-handed.
    """
    r00, r11, r22 = e[0, 0], e[1, 1], e[2, 2]
    # R[i, j] = e[j, i]
    r01, r10 = e[1, 0], e[0, 1]
    r02, r20 = e[2, 0], e[0, 2]
    r12, r21 = e[2, 1], e[1, 2]
    tr = r00 + r11 + r22
    if tr >= r00 and tr >= r11 and tr >= r22:
        s = 2.0 * math.sqrt(max(1.0 + tr, 1e-300))
        out[3] = 0.25 * s
        out[0] = (r21 - r12) / s
        out[1] = (r02 - r20) / s
        out[2] = (r10 - r01) / s
    elif r00 >= r11 and r00 >= r22:
        s = 2.0 * math.sqrt(max(1.0 + r00 - r11 - r22, 1e-300))
        out[3] = (r21 - r12) / s
        out[0] = 0.25 * s
        out[1] = (r01 + r10) / s
        out[2] = (r02 + r20) / s
    elif r11 >= r22:
        s = 2.0 * math.sqrt(max(1.0 + r11 - r00 - r22, 1e-300))
        out[3] = (r02 - r20) / s
        out[0] = (r01 + r10) / s
        out[1] = 0.25 * s
        out[2] = (r12 + r21) / s
    else:
        s = 2.0 * math.sqrt(max(1.0 + r22 - r00 - r11, 1e-300))
        out[3] = (r10 - r01) / s
        out[0] = (r02 + r20) / s
        out[1] = (r12 + r21) / s
        out[2] = 0.25 * s
    n = math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3])
    for i in range(4):
        out[i] /= n


def euler_zxz_quat(phi, theta, psi):
    """q = q_z(φ) ⊗ q_x(θ) ⊗ q_z(ψ) as a tuple: the body frame of z-x-z Euler angles.

    This is world_R_body = R_z(φ) R_x(θ) R_z(ψ) = λᵀ, the transpose of the passive
    λ = λ_ψ λ_θ λ_φ of PHYS0500 §7.6 (which maps world components to body components).
    """
    c1, s1 = math.cos(0.5 * phi), math.sin(0.5 * phi)
    c2, s2 = math.cos(0.5 * theta), math.sin(0.5 * theta)
    c3, s3 = math.cos(0.5 * psi), math.sin(0.5 * psi)
    # q_z(φ) ⊗ q_x(θ) = (c1 s2, s1 s2, s1 c2, c1 c2); then ⊗ q_z(ψ) = (0, 0, s3, c3).
    ax, ay, az, aw = c1 * s2, s1 * s2, s1 * c2, c1 * c2
    return (ax * c3 + ay * s3, ay * c3 - ax * s3, az * c3 + aw * s3, aw * c3 - az * s3)


def quat_from_euler_zxz(phi, theta, psi, out):
    """out = ``euler_zxz_quat(φ, θ, ψ)``."""
    r = euler_zxz_quat(phi, theta, psi)
    for i in range(4):
        out[i] = r[i]


def euler_zxz_angles(q):
    """(φ, θ, ψ) of a unit quaternion, z-x-z as in ``euler_zxz_quat``; θ ∈ [0, π].

    At θ = 0 or π only φ ± ψ is defined: the whole angle goes to φ and ψ = 0 there.
    """
    x, y, z, w = q[0], q[1], q[2], q[3]
    # θ from the symmetry axis: cos θ = R[2, 2]; half-angle form stays accurate near 0 and π.
    a = math.sqrt(w * w + z * z)  # cos(θ/2)
    b = math.sqrt(x * x + y * y)  # sin(θ/2)
    theta = 2.0 * math.atan2(b, a)
    if b < 1e-12 * a:
        return (2.0 * math.atan2(z, w), theta, 0.0)
    if a < 1e-12 * b:
        return (2.0 * math.atan2(y, x), theta, 0.0)
    sum_half = math.atan2(z, w)  # (φ + ψ)/2
    diff_half = math.atan2(y, x)  # (φ − ψ)/2
    phi = sum_half + diff_half
    psi = sum_half - diff_half
    return (math.atan2(math.sin(phi), math.cos(phi)), theta,
            math.atan2(math.sin(psi), math.cos(psi)))


def euler_zxz_from_quat(q, out):
    """out = ``euler_zxz_angles(q)``."""
    r = euler_zxz_angles(q)
    for i in range(3):
        out[i] = r[i]


#: The helpers a rigid-body kernel module lists in its ``kernel_functions`` (each calls only
#: these; ``quat_from_rows`` is listed by the modules that call it).
ROTATION_KERNELS = (quat_product, rotate, rotate_inverse, quat_mul, quat_rotate,
                    quat_rotate_inverse, euler_zxz_quat, quat_from_euler_zxz, euler_zxz_angles,
                    euler_zxz_from_quat)
