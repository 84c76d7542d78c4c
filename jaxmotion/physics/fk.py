"""Forward kinematics of link poses only, in JAX: what ``mjx.kinematics`` gives for ``xpos``/``xquat``.

``mjx.kinematics`` also computes every geom's and site's frame, joint anchors and axes and the
rotation matrices, which the reference windows of the discriminators never read; for them (40k
poses per training iteration) it was the largest single cost of the discriminator update.
``LinkFK`` walks the same tree with quaternions alone, following MuJoCo's rules
(``engine_core_smooth.c``, ``mj_kinematics``):

* a body starts at its parent's frame composed with its fixed offset (``body_pos``, ``body_quat``);
* a free joint sets the frame from ``qpos`` directly (world parent only);
* each hinge rotates the body about its axis through its anchor by ``qpos - qpos0``, a ball joint
  by its quaternion, a slide translates it; joints apply in model order.

The walk goes one tree *level* at a time: every body at depth d is computed at once, as arrays
over those bodies, and the j-th joints of a level's bodies are applied together (bodies with
fewer joints get an identity joint: an index into a zero or an identity quaternion appended to
``qpos``). So the program has a few operations per level and joint slot, not per body and
coordinate: 16 links trace to about a fifth of the operations of a per-body walk, which is what
the compile time of every training program that builds reference windows scales with.

It is checked against MuJoCo C in ``tests/test_fk.py``.
"""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

_FREE, _BALL, _SLIDE, _HINGE = (
    mujoco.mjtJoint.mjJNT_FREE,
    mujoco.mjtJoint.mjJNT_BALL,
    mujoco.mjtJoint.mjJNT_SLIDE,
    mujoco.mjtJoint.mjJNT_HINGE,
)


def _qmul_np(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


def _rot_np(q):
    """Rotation matrix of a unit quaternion, written homogeneous (quadratic) in its components."""
    w, x, y, z = q
    return np.array(
        [
            [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
        ]
    )


def _bilinear(f, n: int, shape) -> np.ndarray:
    """Coefficients C[i, j, ...] of a bilinear f(a, b) = sum_ij a_i b_j C_ij (b = a: symmetric part)."""
    e = np.eye(n)
    return np.stack([np.stack([f(e[i], e[j]) for j in range(n)]) for i in range(n)]).reshape((n, n) + shape)


_QMUL = _bilinear(_qmul_np, 4, (4,)).astype(np.float32)  # [4, 4, 4]
# R(q) is a quadratic form: polarise so that R_ab = sum_ij q_i q_j T_ijab.
_ROT = np.zeros((4, 4, 3, 3))
for _i, _j in itertools.product(range(4), repeat=2):
    _e = np.eye(4)
    _ROT[_i, _j] = 0.25 * (_rot_np(_e[_i] + _e[_j]) - _rot_np(_e[_i] - _e[_j]))
_ROT = _ROT.astype(np.float32)
_EPS = np.zeros((3, 3, 3), np.float32)  # Levi-Civita: (u x v)_k = sum_ij u_i v_j eps_ijk
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    _EPS[_i, _j, _k], _EPS[_j, _i, _k] = 1.0, -1.0


def _qmul(a, b):
    return (a[..., :, None, None] * b[..., None, :, None] * _QMUL).sum((-3, -2))


def _rotmat(q):
    return (q[..., :, None, None, None] * q[..., None, :, None, None] * _ROT).sum((-4, -3))


def _apply(r, v):
    return (r * v[..., None, :]).sum(-1)


def _cross(u, v):
    return (u[..., :, None, None] * v[..., None, :, None] * _EPS).sum((-3, -2))


def _normalize(q):
    return q / jnp.sqrt(jnp.sum(jnp.square(q), -1, keepdims=True))


class _Slot:
    """The j-th joint of every body of one level, as index and constant arrays over the bodies."""

    def __init__(self, n: int, zq: int, iq: int, zv: int):
        self.hinge = np.full(n, zq)  # qpos index of a hinge's angle (the zero otherwise)
        self.hinge_q0 = np.zeros(n, np.float32)
        self.hinge_axis = np.zeros((n, 3), np.float32)
        self.hinge_dof = np.full(n, zv)
        self.ball = np.tile(np.arange(iq, iq + 4), (n, 1))  # an identity quaternion otherwise
        self.ball_dof = np.full((n, 3), zv)
        self.is_ball = np.zeros(n, bool)
        self.slide = np.full(n, zq)
        self.slide_q0 = np.zeros(n, np.float32)
        self.slide_axis = np.zeros((n, 3), np.float32)
        self.slide_dof = np.full(n, zv)
        self.pos = np.zeros((n, 3), np.float32)
        self.has_hinge = self.has_ball = self.has_slide = False


class _Level:
    def __init__(self, bodies, parent_index, m: mujoco.MjModel):
        n = len(bodies)
        zq, iq, zv = m.nq, m.nq + 1, m.nv
        self.bodies = bodies
        self.parent = np.asarray(parent_index)
        self.body_pos = m.body_pos[bodies].astype(np.float32)
        self.body_quat = m.body_quat[bodies].astype(np.float32)
        self.free = np.zeros(n, bool)
        self.free_q = np.tile(np.r_[zq, zq, zq, iq : iq + 4], (n, 1))
        self.free_dof = np.full((n, 6), zv)
        joints = [list(range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])) for b in bodies]
        for i, (b, js) in enumerate(zip(bodies, joints)):
            if any(m.jnt_type[j] == _FREE for j in js):
                if m.body_parentid[b] != 0 or len(js) != 1:
                    raise ValueError(f"body {b}: a free joint must be the only joint of a child of the world")
                self.free[i] = True
                self.free_q[i] = np.arange(m.jnt_qposadr[js[0]], m.jnt_qposadr[js[0]] + 7)
                self.free_dof[i] = np.arange(m.jnt_dofadr[js[0]], m.jnt_dofadr[js[0]] + 6)
                joints[i] = []
        self.slots = [_Slot(n, zq, iq, zv) for _ in range(max((len(js) for js in joints), default=0))]
        for i, js in enumerate(joints):
            for s, j in zip(self.slots, js):
                adr, dof, typ = int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j]), int(m.jnt_type[j])
                s.pos[i] = m.jnt_pos[j]
                if typ == _HINGE:
                    s.hinge[i], s.hinge_q0[i], s.hinge_axis[i], s.hinge_dof[i] = adr, m.qpos0[adr], m.jnt_axis[j], dof
                    s.has_hinge = True
                elif typ == _SLIDE:
                    s.slide[i], s.slide_q0[i], s.slide_axis[i], s.slide_dof[i] = adr, m.qpos0[adr], m.jnt_axis[j], dof
                    s.has_slide = True
                else:
                    s.ball[i], s.ball_dof[i], s.is_ball[i] = np.arange(adr, adr + 4), np.arange(dof, dof + 3), True
                    s.has_ball = True
        # A joint off the link origin, or a slide, moves the link origin off a rotation axis.
        self.arms = any(s.pos.any() or s.has_slide for s in self.slots)


class LinkFK:
    """Link poses of an ``mujoco.MjModel`` as a pure function of ``qpos``."""

    def __init__(self, m: mujoco.MjModel):
        self.nbody = m.nbody
        parent = [int(p) for p in m.body_parentid]
        depth = [0] * m.nbody
        for b in range(1, m.nbody):
            depth[b] = depth[parent[b]] + 1
        self.levels, prev = [], [0]
        for d in range(1, max(depth, default=0) + 1):
            bodies = [b for b in range(1, m.nbody) if depth[b] == d]
            self.levels.append(_Level(bodies, [prev.index(parent[b]) for b in bodies], m))
            prev = bodies
        order = [b for lv in self.levels for b in lv.bodies]
        self.order = np.argsort(order)  # level order -> body order
        self.geom_body = m.geom_bodyid.astype(np.int64)
        self.geom_pos = m.geom_pos.astype(np.float32)
        self.geom_quat = m.geom_quat.astype(np.float32)

    def __call__(self, qpos: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Link positions [..., nbody-1, 3] and unit quaternions [..., nbody-1, 4] of ``qpos``
        [..., nq] (the world body left out)."""
        pos, quat, _, _ = self._walk(qpos, None)
        return pos, quat

    def geom_frames(self, qpos: jax.Array, geoms) -> tuple[jax.Array, jax.Array]:
        """World positions [..., G, 3] and rotation matrices [..., G, 3, 3] of the geoms with ids
        ``geoms`` (of bodies other than the world): MuJoCo's ``geom_xpos``/``geom_xmat``."""
        geoms = np.asarray(geoms)
        if (self.geom_body[geoms] == 0).any():
            raise ValueError("geom_frames: geoms of the world body have no link pose")
        pos, quat = self(qpos)
        b = self.geom_body[geoms] - 1
        xq = jnp.take(quat, b, axis=-2)
        gpos = jnp.take(pos, b, axis=-2) + _apply(_rotmat(xq), self.geom_pos[geoms])
        return gpos, _rotmat(_qmul(xq, self.geom_quat[geoms]))

    def frames(self, qpos: jax.Array, qvel: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
        """Link positions, quaternions, linear velocities of the link origins and angular
        velocities, all in the world frame: [..., nbody-1, 3 | 4 | 3 | 3] (world body left out).

        Velocities follow the tree: a link moves rigidly with its parent (``v_p + w_p x (x - x_p)``),
        and each of its joints adds its own rate (hinge: ``axis * qdot`` about its anchor; free
        joint: ``qvel[:3]`` is the origin's world velocity, ``qvel[3:6]`` the angular velocity in
        the link frame, as MuJoCo defines them)."""
        return self._walk(qpos, qvel)

    def _walk(self, qpos, qvel):
        batch = qpos.shape[:-1]
        # Padding targets: a zero coordinate and an identity quaternion after qpos, a zero rate after qvel.
        qx = jnp.concatenate([qpos, jnp.broadcast_to(jnp.asarray([0, 1, 0, 0, 0], qpos.dtype), batch + (5,))], -1)
        vx = None if qvel is None else jnp.concatenate([qvel, jnp.zeros(batch + (1,), qvel.dtype)], -1)
        outs, prev = [], None
        for lv in self.levels:
            n = len(lv.bodies)
            if prev is None:  # children of the world
                x = jnp.broadcast_to(lv.body_pos, batch + (n, 3))
                r = jnp.broadcast_to(lv.body_quat, batch + (n, 4))
                p = v_p = w_p = None
            else:
                p, q_p, v_p, w_p = (None if a is None else jnp.take(a, lv.parent, axis=-2) for a in prev)
                x = p + _apply(_rotmat(q_p), lv.body_pos)
                r = _qmul(q_p, lv.body_quat)
            lin, ang, arms = [], [], []
            if lv.free.any():
                fq = qx[..., lv.free_q]
                x = jnp.where(lv.free[:, None], fq[..., :3], x)
                r = jnp.where(lv.free[:, None], _normalize(fq[..., 3:]), r)
                if vx is not None:
                    fv = vx[..., lv.free_dof]  # zero rates for the bodies without a free joint
                    lin.append(fv[..., :3])
                    ang.append(_apply(_rotmat(r), fv[..., 3:]))
            for s in lv.slots:
                r0 = r
                R0 = _rotmat(r0) if (s.pos.any() or s.has_slide) else None
                anchor = x + _apply(R0, s.pos) if s.pos.any() else x
                dq = None
                if s.has_hinge:
                    half = 0.5 * (qx[..., s.hinge] - s.hinge_q0)
                    dq = jnp.concatenate([jnp.cos(half)[..., None], jnp.sin(half)[..., None] * s.hinge_axis], -1)
                if s.has_ball:
                    qb = _normalize(qx[..., s.ball])
                    dq = qb if dq is None else jnp.where(s.is_ball[:, None], qb, dq)
                if dq is not None:
                    r = _qmul(r0, dq)
                R = _rotmat(r) if (s.pos.any() or vx is not None) else None
                x = anchor - _apply(R, s.pos) if s.pos.any() else anchor
                if s.has_slide:
                    x = x + _apply(R0, s.slide_axis * (qx[..., s.slide] - s.slide_q0)[..., None])
                if vx is None:
                    continue
                w_loc = 0.0
                if s.has_hinge:
                    w_loc = s.hinge_axis * vx[..., s.hinge_dof][..., None]
                if s.has_ball:
                    w_loc = w_loc + vx[..., s.ball_dof]
                if s.has_hinge or s.has_ball:
                    ang.append(_apply(R, w_loc))
                    arms.append((ang[-1], anchor))
                if s.has_slide:
                    lin.append(_apply(R0, s.slide_axis * vx[..., s.slide_dof][..., None]))
            r = _normalize(r)
            if vx is None:
                prev = (x, r, None, None)
            else:
                v = sum(lin) if lin else jnp.zeros_like(x)
                w = sum(ang) if ang else jnp.zeros_like(x)
                if p is not None:
                    v, w = v + v_p + _cross(w_p, x - p), w + w_p
                if lv.arms:  # rotations about points other than the link origin
                    v = v + sum(_cross(w_k, x - a_k) for w_k, a_k in arms)
                prev = (x, r, v, w)
            outs.append(prev)
        cat = lambda i: (
            None if outs[0][i] is None else jnp.take(jnp.concatenate([o[i] for o in outs], -2), self.order, axis=-2)
        )
        return cat(0), cat(1), cat(2), cat(3)
