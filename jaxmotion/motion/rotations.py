"""Quaternion helpers (wxyz, Hamilton product, active rotations), for numpy and JAX arrays.

Every function broadcasts over leading axes. The array module follows the inputs: if any input is a
``jax.Array`` (including tracers under ``jit``/``vmap``) the result is computed with ``jax.numpy``,
otherwise with ``numpy`` (so the loaders keep float64 precision). There is no Python branching on
array values, so everything is ``jit``/``vmap`` friendly.

Conventions: quaternions are ``(w, x, y, z)``; ``quat_rotate(q, v)`` rotates ``v`` by ``q``
(``R(q) @ v``); ``quat_mul(a, b)`` is the rotation ``b`` followed by ``a`` (``R(a) @ R(b)``).
Euler angles are intrinsic X-Y-Z: ``R = Rx(a) @ Ry(b) @ Rz(c)``, which is how MuJoCo composes a
body's x, y, z hinges.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def _xp(*arrays):
    """``jax.numpy`` if any argument is a JAX array (or tracer), else ``numpy``."""
    return jnp if any(isinstance(a, jax.Array) for a in arrays) else np


def _eps(x, f64: float, f32: float) -> float:
    return f64 if getattr(x, "dtype", None) == np.float64 else f32


def quat_identity(shape: tuple[int, ...] = ()) -> np.ndarray:
    """Identity quaternions.

    Args:
        shape: leading shape.

    Returns:
        [*shape, 4] float64 array of (1, 0, 0, 0).
    """
    q = np.zeros((*shape, 4))
    q[..., 0] = 1.0
    return q


def quat_mul(a, b):
    """Hamilton product ``a * b`` (apply ``b`` first, then ``a``).

    Args:
        a: [..., 4] wxyz.
        b: [..., 4] wxyz (broadcast against ``a``).

    Returns:
        [..., 4] wxyz.
    """
    xp = _xp(a, b)
    aw, ax, ay, az = (a[..., i] for i in range(4))
    bw, bx, by, bz = (b[..., i] for i in range(4))
    return xp.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def quat_conj(q):
    """Conjugate (= inverse for unit quaternions). q: [..., 4] -> [..., 4]."""
    xp = _xp(q)
    return xp.concatenate([q[..., :1], -q[..., 1:]], axis=-1)


def quat_normalize(q):
    """Unit quaternion. q: [..., 4] -> [..., 4] (a zero input gives NaN: callers validate)."""
    xp = _xp(q)
    return q / xp.linalg.norm(q, axis=-1, keepdims=True)


def quat_rotate(q, v):
    """Rotates vectors by unit quaternions.

    Args:
        q: [..., 4] wxyz.
        v: [..., 3] (broadcast against ``q``).

    Returns:
        [..., 3] ``R(q) @ v``.
    """
    xp = _xp(q, v)
    w = q[..., :1]
    u = q[..., 1:]
    uv = xp.cross(u, v)
    return v + 2.0 * (w * uv + xp.cross(u, uv))


def quat_rotate_inv(q, v):
    """Rotates vectors by the inverse of ``q``: ``R(q).T @ v``. q: [..., 4], v: [..., 3] -> [..., 3]."""
    return quat_rotate(quat_conj(q), v)


def quat_to_mat(q):
    """Rotation matrices of unit quaternions. q: [..., 4] wxyz -> [..., 3, 3]."""
    xp = _xp(q)
    w, x, y, z = (q[..., i] for i in range(4))
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return xp.stack([xp.stack(r, axis=-1) for r in rows], axis=-2)


def mat_to_quat(m):
    """Unit quaternions of rotation matrices (Shepperd's method, branch-free).

    Args:
        m: [..., 3, 3] rotation matrices.

    Returns:
        [..., 4] wxyz, normalised (sign not canonicalised).
    """
    xp = _xp(m)
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    t = xp.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], axis=-1)
    # Each candidate is proportional to q; the one with the largest pivot is best conditioned.
    cands = xp.stack(
        [
            xp.stack([t[..., 0], m21 - m12, m02 - m20, m10 - m01], axis=-1),
            xp.stack([m21 - m12, t[..., 1], m01 + m10, m02 + m20], axis=-1),
            xp.stack([m02 - m20, m01 + m10, t[..., 2], m12 + m21], axis=-1),
            xp.stack([m10 - m01, m02 + m20, m12 + m21, t[..., 3]], axis=-1),
        ],
        axis=-2,
    )
    idx = xp.argmax(t, axis=-1)[..., None, None]
    q = xp.take_along_axis(cands, idx, axis=-2)[..., 0, :]
    return quat_normalize(q)


def quat_from_axis_angle(axis, angle):
    """Quaternion of a rotation by ``angle`` about a unit ``axis``.

    Args:
        axis: [..., 3] unit vectors.
        angle: [...] radians.

    Returns:
        [..., 4] wxyz.
    """
    xp = _xp(axis, angle)
    half = 0.5 * xp.asarray(angle)[..., None]
    return xp.concatenate([xp.cos(half), xp.sin(half) * axis], axis=-1)


def quat_from_euler_xyz(e):
    """Quaternion of intrinsic X-Y-Z Euler angles, ``R = Rx(a) Ry(b) Rz(c)``.

    Args:
        e: [..., 3] angles (a, b, c) in radians.

    Returns:
        [..., 4] wxyz.
    """
    xp = _xp(e)
    ch, sh = xp.cos(0.5 * e), xp.sin(0.5 * e)
    z = xp.zeros_like(ch[..., 0])
    qx = xp.stack([ch[..., 0], sh[..., 0], z, z], axis=-1)
    qy = xp.stack([ch[..., 1], z, sh[..., 1], z], axis=-1)
    qz = xp.stack([ch[..., 2], z, z, sh[..., 2]], axis=-1)
    return quat_mul(quat_mul(qx, qy), qz)


def euler_xyz_from_quat(q):
    """Intrinsic X-Y-Z Euler angles of unit quaternions (inverse of ``quat_from_euler_xyz``).

    Returns ``a, c`` in (-pi, pi] and ``b`` in [-pi/2, pi/2]. At gimbal lock (``cos b`` ~ 0)
    ``c`` is set to 0 and ``a`` carries the whole rotation about the common axis.

    Args:
        q: [..., 4] wxyz unit quaternions.

    Returns:
        [..., 3] angles (a, b, c).
    """
    xp = _xp(q)
    w, x, y, z = (q[..., i] for i in range(4))
    r00 = 1 - 2 * (y * y + z * z)
    r01 = 2 * (x * y - w * z)
    r02 = 2 * (x * z + w * y)
    r11 = 1 - 2 * (x * x + z * z)
    r12 = 2 * (y * z - w * x)
    r21 = 2 * (y * z + w * x)
    r22 = 1 - 2 * (x * x + y * y)
    cb = xp.sqrt(r12 * r12 + r22 * r22)
    b = xp.arctan2(r02, cb)
    lock = cb < _eps(q, 1e-9, 1e-5)
    a = xp.where(lock, xp.arctan2(r21, r11), xp.arctan2(-r12, r22))
    c = xp.where(lock, xp.zeros_like(b), xp.arctan2(-r01, r00))
    return xp.stack([a, b, c], axis=-1)


def twist_angle(q, axis: int):
    """Angle of the rotation about one coordinate axis (swing-twist decomposition).

    For a pure rotation about ``axis`` this is exact; off-axis components are dropped.

    Args:
        q: [..., 4] wxyz unit quaternions.
        axis: 0, 1 or 2 (x, y, z).

    Returns:
        [...] angle in (-pi, pi].
    """
    xp = _xp(q)
    ang = 2.0 * xp.arctan2(q[..., 1 + axis], q[..., 0])
    return wrap_angle(ang)


def wrap_angle(a):
    """Wraps angles to (-pi, pi]. a: [...] -> [...]."""
    xp = _xp(a)
    return xp.pi - xp.mod(xp.pi - a, 2 * xp.pi)


def slerp(q0, q1, t):
    """Spherical linear interpolation along the shortest path.

    Uses normalised linear interpolation when the two rotations are (nearly) equal, selected with
    ``where`` (no Python branching), so it is safe under ``jit``/``vmap``. (Near equal rotations the
    slerp weights do not depend on the exact angle, so ``arccos`` precision does not matter.)

    Args:
        q0: [..., 4] wxyz unit quaternions (t = 0).
        q1: [..., 4] wxyz unit quaternions (t = 1).
        t: [...] or scalar interpolation fraction.

    Returns:
        [..., 4] wxyz unit quaternions.
    """
    xp = _xp(q0, q1, t)
    t = xp.asarray(t)[..., None]
    d = xp.sum(q0 * q1, axis=-1, keepdims=True)
    sign = xp.where(d < 0, -1.0, 1.0)
    theta = xp.arccos(xp.minimum(d * sign, 1.0))  # angle between q0 and the nearer of +-q1
    small = theta < 1e-6
    inv_sin = 1.0 / xp.where(small, 1.0, xp.sin(theta))
    w0 = xp.where(small, 1.0 - t, xp.sin((1.0 - t) * theta) * inv_sin)
    w1 = xp.where(small, t, xp.sin(t * theta) * inv_sin) * sign
    return quat_normalize(w0 * q0 + w1 * q1)


def quat_to_axis_angle(q):
    """Axis and angle of unit quaternions (shortest rotation, angle in [0, pi]).

    Args:
        q: [..., 4] wxyz.

    Returns:
        (axis [..., 3] unit, (1, 0, 0) for the identity; angle [...] radians).
    """
    xp = _xp(q)
    q = xp.where(q[..., :1] < 0, -q, q)
    s = xp.linalg.norm(q[..., 1:], axis=-1)
    angle = 2.0 * xp.arctan2(s, q[..., 0])
    tiny = s < 1e-12
    safe_s = xp.where(tiny, 1.0, s)
    default = xp.zeros_like(q[..., 1:]) + xp.asarray([1.0, 0.0, 0.0], dtype=q.dtype)
    axis = xp.where(tiny[..., None], default, q[..., 1:] / safe_s[..., None])
    return axis, angle


def quat_to_exp_map(q):
    """Rotation vectors (axis * angle, angle in [0, pi]) of unit quaternions. [..., 4] -> [..., 3]."""
    xp = _xp(q)
    q = xp.where(q[..., :1] < 0, -q, q)
    s = xp.linalg.norm(q[..., 1:], axis=-1)
    angle = 2.0 * xp.arctan2(s, q[..., 0])
    tiny = s < _eps(q, 1e-12, 1e-6)
    # angle / s -> 2 / w as s -> 0.
    scale = xp.where(tiny, 2.0 / xp.maximum(q[..., 0], 1e-6), angle / xp.where(tiny, 1.0, s))
    return q[..., 1:] * scale[..., None]


def exp_map_to_quat(v):
    """Unit quaternions of rotation vectors. v: [..., 3] -> [..., 4] wxyz."""
    xp = _xp(v)
    angle = xp.linalg.norm(v, axis=-1, keepdims=True)
    tiny = angle < 1e-6
    # sin(angle / 2) / angle -> 1/2 - angle^2 / 48.
    scale = xp.where(tiny, 0.5 - angle * angle / 48.0, xp.sin(0.5 * angle) / xp.where(tiny, 1.0, angle))
    return xp.concatenate([xp.cos(0.5 * angle), v * scale], axis=-1)


def heading_angle(q):
    """Yaw of the rotated x axis about world z. q: [..., 4] wxyz -> [...] radians in (-pi, pi]."""
    xp = _xp(q)
    w, x, y, z = (q[..., i] for i in range(4))
    return xp.arctan2(2 * (x * y + w * z), 1 - 2 * (y * y + z * z))


def _yaw_quat(h):
    xp = _xp(h)
    z = xp.zeros_like(h)
    return xp.stack([xp.cos(0.5 * h), z, z, xp.sin(0.5 * h)], axis=-1)


def heading_quat(q):
    """The heading (pure yaw about z) part of ``q``. q: [..., 4] -> [..., 4] wxyz."""
    return _yaw_quat(heading_angle(q))


def heading_inv(q):
    """Inverse of ``heading_quat(q)``: maps world vectors into the heading frame. [..., 4] -> [..., 4]."""
    return _yaw_quat(-heading_angle(q))


def quat_to_tan_norm(q):
    """6D rotation features: the first and third columns of the rotation matrix.

    Args:
        q: [..., 4] wxyz.

    Returns:
        [..., 6] = (R @ e_x, R @ e_z).
    """
    xp = _xp(q)
    m = quat_to_mat(q)
    return xp.concatenate([m[..., :, 0], m[..., :, 2]], axis=-1)


def quat_angle_between(q0, q1):
    """Rotation angle of ``q1 * conj(q0)`` (geodesic distance). [..., 4] x2 -> [...] in [0, pi]."""
    xp = _xp(q0, q1)
    d = xp.abs(xp.sum(q0 * q1, axis=-1))
    return 2.0 * xp.arccos(xp.clip(d, 0.0, 1.0))


def quat_make_continuous(q):
    """Flips signs along axis 0 so consecutive quaternions have a non-negative dot product.

    Args:
        q: [T, ..., 4] numpy array.

    Returns:
        [T, ..., 4] numpy array (same rotations), the first frame with w >= 0.
    """
    q = np.array(q, dtype=np.float64, copy=True)
    q[0] = np.where(q[0, ..., :1] < 0, -q[0], q[0])
    flips = np.sum(q[1:] * q[:-1], axis=-1) < 0
    sign = np.where(np.cumsum(flips, axis=0) % 2 == 1, -1.0, 1.0)
    q[1:] *= sign[..., None]
    return q
