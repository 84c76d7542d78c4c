"""The lean forward kinematics (``physics/fk.py``) against MuJoCo C: poses and velocities of every
link, on both characters and on a model with the joint kinds the characters lack."""

from __future__ import annotations

import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from jaxmotion.physics import sim
from jaxmotion.physics.fk import LinkFK

# Ball, slide and offset-anchor hinges, a rotated body offset, and a free body: the paths the
# humanoids (free root + hinges at the link origins) do not exercise.
_ODD = """
<mujoco>
  <worldbody>
    <body name="root" pos="0 0 1">
      <freejoint/>
      <geom type="sphere" size="0.1"/>
      <body name="a" pos="0.2 0.1 0" quat="0.9 0.1 0.3 -0.2">
        <joint type="ball" pos="0.05 0 0.02"/>
        <geom type="capsule" size="0.04 0.1"/>
        <body name="b" pos="0 0 -0.3">
          <joint type="slide" axis="0.6 0 0.8"/>
          <joint type="hinge" axis="0 1 0" pos="0.03 -0.02 0.1"/>
          <geom type="box" size="0.05 0.05 0.05"/>
        </body>
      </body>
      <body name="c" pos="-0.2 0 0.1">
        <joint type="hinge" axis="1 1 0"/>
        <joint type="hinge" axis="0 0 1" pos="0 0.05 0"/>
        <geom type="sphere" size="0.05"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _random_state(m: mujoco.MjModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    qpos = np.zeros(m.nq)
    for j in range(m.njnt):
        adr, typ = m.jnt_qposadr[j], m.jnt_type[j]
        if typ == mujoco.mjtJoint.mjJNT_FREE:
            q = rng.normal(size=4)
            qpos[adr : adr + 7] = np.concatenate([rng.normal(size=3), q / np.linalg.norm(q)])
        elif typ == mujoco.mjtJoint.mjJNT_BALL:
            q = rng.normal(size=4)
            qpos[adr : adr + 4] = q / np.linalg.norm(q)
        else:
            qpos[adr] = rng.uniform(-1.5, 1.5)
    return qpos, rng.normal(size=m.nv) * 2.0


@pytest.mark.parametrize("model", ["humanoid", "sword_shield", "odd"])
def test_link_poses_and_velocities_match_mujoco(model):
    if model == "odd":
        m = mujoco.MjModel.from_xml_string(_ODD)
    else:
        m = sim.mj_model(sim.PhysicsConfig(sword_shield=model == "sword_shield"))
    d = mujoco.MjData(m)
    fk = LinkFK(m)
    rng = np.random.default_rng(3)
    states = [_random_state(m, rng) for _ in range(6)]
    qpos = jnp.asarray(np.stack([s[0] for s in states]), jnp.float32)
    qvel = jnp.asarray(np.stack([s[1] for s in states]), jnp.float32)
    pos, quat, lin, ang = (np.asarray(x) for x in fk.frames(qpos, qvel))
    pos_only, quat_only = (np.asarray(x) for x in fk(qpos))
    geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] != 0]
    gpos, gmat = (np.asarray(x) for x in fk.geom_frames(qpos, geoms))
    np.testing.assert_array_equal(pos_only, pos)
    np.testing.assert_array_equal(quat_only, quat)
    assert pos.shape == (6, m.nbody - 1, 3) and quat.shape == (6, m.nbody - 1, 4)
    res = np.zeros(6)
    for i, (qp, qv) in enumerate(states):
        d.qpos[:], d.qvel[:] = qp, qv
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
        np.testing.assert_allclose(pos[i], d.xpos[1:], atol=2e-5)
        np.testing.assert_allclose(gpos[i], d.geom_xpos[geoms], atol=2e-5)
        np.testing.assert_allclose(gmat[i], d.geom_xmat[geoms].reshape(-1, 3, 3), atol=2e-5)
        sign = np.sign(np.sum(quat[i] * d.xquat[1:], -1, keepdims=True))
        np.testing.assert_allclose(quat[i] * sign, d.xquat[1:], atol=2e-5)
        for b in range(1, m.nbody):
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_XBODY, b, res, 0)  # world frame
            np.testing.assert_allclose(ang[i, b - 1], res[:3], atol=1e-4)
            np.testing.assert_allclose(lin[i, b - 1], res[3:], atol=1e-4)


def test_world_geoms_have_no_link_frame():
    m = mujoco.MjModel.from_xml_string(_ODD.replace("<worldbody>", '<worldbody><geom type="plane" size="1 1 1"/>'))
    with pytest.raises(ValueError, match="world"):
        LinkFK(m).geom_frames(jnp.zeros(m.nq), [0])


def test_batch_shapes_broadcast():
    m = sim.mj_model(sim.PhysicsConfig())
    fk = LinkFK(m)
    qpos = jnp.tile(jnp.asarray(m.qpos0, jnp.float32), (2, 3, 1))
    pos, quat = fk(qpos)
    assert pos.shape == (2, 3, m.nbody - 1, 3) and quat.shape == (2, 3, m.nbody - 1, 4)
    assert np.isfinite(np.asarray(pos)).all()
