"""Rotations of the linescan model: quaternions, rotation matrices and the orbital frame.

Quaternions are ``(w, x, y, z)``, scalar first, Hamilton convention, *active*: the matrix
``R(q)`` maps source-frame vectors to the target frame, ``v_target = R @ v_source``. All
functions are vectorised over leading axes ``(...)``.
"""

from __future__ import annotations

import numpy as np

from geoblock.typing import ArrayLike, Float64Array

__all__ = ["matrix_to_quaternion", "orbital_frame", "quaternion_to_matrix", "rotation_xyz"]


def orbital_frame(position_m: ArrayLike, velocity_m_s: ArrayLike) -> Float64Array:
    """The orbital (LVLH) frame of a satellite state.

    Parameters
    ----------
    position_m : array_like, (..., 3)
        ECEF position, metres.
    velocity_m_s : array_like, (..., 3)
        ECEF velocity, metres per second.

    Returns
    -------
    ndarray, (..., 3, 3)
        Columns ``x_o, y_o, z_o`` in ECEF: ``z_o = -P/|P|`` (towards the Earth's centre),
        ``y_o = z_o x V / |z_o x V|``, ``x_o = y_o x z_o`` (about the flight direction). It maps
        orbital-frame vectors to ECEF: ``v_ecef = M @ v_orb``.
    """
    p = np.asarray(position_m, dtype=np.float64)
    v = np.asarray(velocity_m_s, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = -p / np.linalg.norm(p, axis=-1, keepdims=True)
        y = np.cross(z, v)
        y = y / np.linalg.norm(y, axis=-1, keepdims=True)
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=-1)


def quaternion_to_matrix(q: ArrayLike) -> Float64Array:
    """Rotation matrices of quaternions ``(w, x, y, z)`` (Hamilton, active).

    Parameters
    ----------
    q : array_like, (..., 4)
        Quaternions, scalar first; normalised here.

    Returns
    -------
    ndarray, (..., 3, 3)
        ``R`` with ``v_target = R @ v_source``.
    """
    quat = np.asarray(q, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        quat = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
    w, x, y, z = quat[..., 0], quat[..., 1], quat[..., 2], quat[..., 3]
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    out = np.empty(quat.shape[:-1] + (3, 3))
    out[..., 0, 0] = 1.0 - 2.0 * (yy + zz)
    out[..., 0, 1] = 2.0 * (xy - wz)
    out[..., 0, 2] = 2.0 * (xz + wy)
    out[..., 1, 0] = 2.0 * (xy + wz)
    out[..., 1, 1] = 1.0 - 2.0 * (xx + zz)
    out[..., 1, 2] = 2.0 * (yz - wx)
    out[..., 2, 0] = 2.0 * (xz - wy)
    out[..., 2, 1] = 2.0 * (yz + wx)
    out[..., 2, 2] = 1.0 - 2.0 * (xx + yy)
    return out


def matrix_to_quaternion(r: ArrayLike) -> Float64Array:
    """Unit quaternions ``(w, x, y, z)`` of rotation matrices (inverse of
    :func:`quaternion_to_matrix`), with ``w >= 0``.

    Parameters
    ----------
    r : array_like, (..., 3, 3)
        Rotation matrices.

    Returns
    -------
    ndarray, (..., 4)
    """
    m = np.asarray(r, dtype=np.float64)
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    # Shepperd: build from the largest of 4w^2, 4x^2, 4y^2, 4z^2 for numerical stability
    cands = np.stack([
        np.stack([1 + m00 + m11 + m22, m[..., 2, 1] - m[..., 1, 2],
                  m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], axis=-1),
        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + m00 - m11 - m22,
                  m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], axis=-1),
        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0],
                  1 - m00 + m11 - m22, m[..., 1, 2] + m[..., 2, 1]], axis=-1),
        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0],
                  m[..., 1, 2] + m[..., 2, 1], 1 - m00 - m11 + m22], axis=-1),
    ], axis=-2)  # (..., 4 candidates, 4 components); candidate k has 4 q_k^2 at index k
    diag = np.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22,
                     1 - m00 + m11 - m22, 1 - m00 - m11 + m22], axis=-1)
    k = np.argmax(diag, axis=-1)
    q = np.take_along_axis(cands, k[..., None, None], axis=-2)[..., 0, :]
    with np.errstate(invalid="ignore", divide="ignore"):
        q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def rotation_xyz(roll: ArrayLike, pitch: ArrayLike, yaw: ArrayLike) -> Float64Array:
    """``Rx(roll) @ Ry(pitch) @ Rz(yaw)``, angles in radians, (..., 3, 3)."""
    a, b, c = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (roll, pitch, yaw)))
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    out = np.empty(a.shape + (3, 3))
    # Rx @ Ry @ Rz written out
    out[..., 0, 0] = cb * cc
    out[..., 0, 1] = -cb * sc
    out[..., 0, 2] = sb
    out[..., 1, 0] = sa * sb * cc + ca * sc
    out[..., 1, 1] = -sa * sb * sc + ca * cc
    out[..., 1, 2] = -sa * cb
    out[..., 2, 0] = -ca * sb * cc + sa * sc
    out[..., 2, 1] = ca * sb * sc + sa * cc
    out[..., 2, 2] = ca * cb
    return out
