"""Forward kinematics of link poses only, in JAX: what ``mjx.kinematics`` gives for ``xpos``/``xquat``.

``mjx.kinematics`` also computes every geom's and site's frame, joint anchors and axes and the
rotation matrices, which the reference windows of the discriminators never read; for them (40k
poses per training iteration) it was the largest single cost of the discriminator update (48 of
78 us per sample on the 2-core CPU). ``LinkFK`` walks the same tree with quaternions alone,
following MuJoCo's rules (``engine_core_smooth.c``, ``mj_kinematics``):

* a body starts at its parent's frame composed with its fixed offset (``body_pos``, ``body_quat``);
* a free joint sets the frame from ``qpos`` directly (world parent only);
* each hinge rotates the body about its axis through its anchor by ``qpos - qpos0``, a ball joint
  by its quaternion, a slide translates it; joints apply in model order.

It is checked against MuJoCo C and MJX in ``tests/test_fk.py``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

_FREE, _BALL, _SLIDE, _HINGE = (mujoco.mjtJoint.mjJNT_FREE, mujoco.mjtJoint.mjJNT_BALL,
                                mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_HINGE)

# Quaternions and vectors are tuples of components, each an array or a Python float. Constant
# components (the model's offsets and axes) fold at trace time: a product with a constant 0 is
# dropped, so a hinge about a coordinate axis costs a quarter of a general rotation.


def _mul(a, b):
    if isinstance(a, float) and isinstance(b, float):
        return a * b
    if (isinstance(a, float) and a == 0.0) or (isinstance(b, float) and b == 0.0):
        return 0.0
    if isinstance(a, float) and a == 1.0:
        return b
    if isinstance(b, float) and b == 1.0:
        return a
    return a * b


def _add(*terms):
    out = 0.0
    for t in terms:
        if isinstance(t, float) and t == 0.0:
            continue
        out = t if (isinstance(out, float) and out == 0.0) else out + t
    return out


def _neg(a):
    return -a


def _qmul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (_add(_mul(aw, bw), _neg(_mul(ax, bx)), _neg(_mul(ay, by)), _neg(_mul(az, bz))),
            _add(_mul(aw, bx), _mul(ax, bw), _mul(ay, bz), _neg(_mul(az, by))),
            _add(_mul(aw, by), _neg(_mul(ax, bz)), _mul(ay, bw), _mul(az, bx)),
            _add(_mul(aw, bz), _mul(ax, by), _neg(_mul(ay, bx)), _mul(az, bw)))


def _cross(u, v):
    return (_add(_mul(u[1], v[2]), _neg(_mul(u[2], v[1]))),
            _add(_mul(u[2], v[0]), _neg(_mul(u[0], v[2]))),
            _add(_mul(u[0], v[1]), _neg(_mul(u[1], v[0]))))


def _rotate(q, v):
    """R(q) v = v + 2 (w (u x v) + u x (u x v)) for a unit quaternion q = (w, u)."""
    if all(isinstance(c, float) and c == 0.0 for c in v):
        return (0.0, 0.0, 0.0)
    u = q[1:]
    uv = _cross(u, v)
    uuv = _cross(u, uv)
    return tuple(_add(v[i], _mul(2.0, _add(_mul(q[0], uv[i]), uuv[i]))) for i in range(3))


def _const(x) -> tuple:
    return tuple(float(c) for c in x)


def _normalize(q):
    n = jnp.sqrt(sum(jnp.square(jnp.asarray(c)) for c in q))
    return tuple(c / n for c in q)


class LinkFK:
    """Link poses of an ``mujoco.MjModel`` as a pure function of ``qpos``."""

    def __init__(self, m: mujoco.MjModel):
        self.nbody = m.nbody
        self.parent = [int(p) for p in m.body_parentid]
        self.body_pos = [_const(m.body_pos[b]) for b in range(m.nbody)]
        self.body_quat = [_const(m.body_quat[b]) for b in range(m.nbody)]
        self.joints = []  # per body: (type, qposadr, axis, pos, qpos0, dofadr) in model order
        for b in range(m.nbody):
            js = []
            for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
                typ = int(m.jnt_type[j])
                if typ == _FREE and self.parent[b] != 0:
                    raise ValueError(f"body {b}: a free joint below another body is not supported")
                adr = int(m.jnt_qposadr[j])
                js.append((typ, adr, _const(m.jnt_axis[j]), _const(m.jnt_pos[j]), float(m.qpos0[adr]),
                           int(m.jnt_dofadr[j])))
            self.joints.append(js)

    def __call__(self, qpos: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Link positions [..., nbody-1, 3] and unit quaternions [..., nbody-1, 4] of ``qpos``
        [..., nq] (the world body left out)."""
        pos, quat, _, _ = self._walk(qpos, None)
        return pos, quat

    def frames(self, qpos: jax.Array, qvel: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
        """Link positions, quaternions, linear velocities of the link origins and angular
        velocities, all in the world frame: [..., nbody-1, 3 | 4 | 3 | 3] (world body left out).

        Velocities follow the tree: a link moves rigidly with its parent (``v_p + w_p x (x - x_p)``),
        and each of its joints adds its own rate (hinge: ``axis * qdot`` about its anchor; free
        joint: ``qvel[:3]`` is the origin's world velocity, ``qvel[3:6]`` the angular velocity in
        the link frame, as MuJoCo defines them)."""
        return self._walk(qpos, qvel)

    def _walk(self, qpos, qvel):
        qs = jnp.moveaxis(qpos, -1, 0)  # one contiguous array per coordinate
        vs = None if qvel is None else jnp.moveaxis(qvel, -1, 0)
        zero3 = (0.0, 0.0, 0.0)
        pos, quat, lin, ang = [zero3], [(1.0, 0.0, 0.0, 0.0)], [zero3], [zero3]
        for b in range(1, self.nbody):
            p, q = pos[self.parent[b]], quat[self.parent[b]]
            x = tuple(_add(p[i], d) for i, d in enumerate(_rotate(q, self.body_pos[b])))
            r = _qmul(q, self.body_quat[b])
            rates = []  # (kind, world vector, anchor): what each joint adds to the velocities
            # The link origin stays on every rotation axis only if every joint sits at the origin.
            offset = any(any(j[3]) for j in self.joints[b])
            for typ, adr, axis, jpos, q0, dadr in self.joints[b]:
                if typ == _FREE:
                    x = (qs[adr], qs[adr + 1], qs[adr + 2])
                    r = _normalize(tuple(qs[adr + 3 + i] for i in range(4)))
                    if vs is not None:
                        rates.append(("lin", (vs[dadr], vs[dadr + 1], vs[dadr + 2]), None))
                        rates.append(("ang", _rotate(r, (vs[dadr + 3], vs[dadr + 4], vs[dadr + 5])), x))
                    continue
                anchor = tuple(_add(x[i], d) for i, d in enumerate(_rotate(r, jpos)))
                if typ == _SLIDE:
                    t = _rotate(r, axis)
                    x = tuple(_add(x[i], _mul(t[i], qs[adr] - q0)) for i in range(3))
                    if vs is not None:
                        rates.append(("lin", tuple(_mul(c, vs[dadr]) for c in t), None))
                    continue
                if typ == _HINGE:
                    half = 0.5 * (qs[adr] - q0)
                    s = jnp.sin(half)
                    dq = (jnp.cos(half),) + tuple(_mul(s, a) for a in axis)
                    if vs is not None:
                        rates.append(("ang", tuple(_mul(c, vs[dadr]) for c in _rotate(r, axis)),
                                      anchor if offset else None))
                    r = _qmul(r, dq)
                else:  # ball: angular velocity in the frame after the rotation
                    r = _qmul(r, _normalize(tuple(qs[adr + i] for i in range(4))))
                    if vs is not None:
                        rates.append(("ang", _rotate(r, (vs[dadr], vs[dadr + 1], vs[dadr + 2])),
                                      anchor if offset else None))
                x = tuple(_add(anchor[i], _neg(d)) for i, d in enumerate(_rotate(r, jpos)))
            pos.append(x)
            quat.append(_normalize(r))
            if vs is None:
                continue
            w_p = ang[self.parent[b]]
            off = tuple(_add(x[i], _neg(p[i])) for i in range(3))
            v = tuple(_add(lin[self.parent[b]][i], c) for i, c in enumerate(_cross(w_p, off)))
            w = w_p
            for kind, vec, anchor in rates:
                if kind == "lin":
                    v = tuple(_add(v[i], vec[i]) for i in range(3))
                    continue
                w = tuple(_add(w[i], vec[i]) for i in range(3))
                if anchor is not None:  # rotation about a point other than the link origin
                    arm = tuple(_add(x[i], _neg(anchor[i])) for i in range(3))
                    v = tuple(_add(v[i], c) for i, c in enumerate(_cross(vec, arm)))
            lin.append(v)
            ang.append(w)
        like = qs[0]
        arr = lambda t: jnp.stack([jnp.broadcast_to(jnp.asarray(c, like.dtype), like.shape) for c in t], -1)
        out = lambda xs: jnp.stack([arr(c) for c in xs[1:]], -2)
        if vs is None:
            return out(pos), out(quat), None, None
        return out(pos), out(quat), out(lin), out(ang)
