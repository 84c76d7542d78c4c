"""Props: free bodies in the character's scene (balls), owned by a task.

A scene is the character (``physics/character.py``) plus ``PhysicsConfig.props``: each a free
sphere written after the character, so the character keeps ``qpos[:7 + n_dof]`` and
``qvel[:6 + n_dof]`` and prop ``i`` has ``qpos[nq_c + 7i : nq_c + 7i + 7]`` (position, quaternion
w-x-y-z) and ``qvel[nv_c + 6i : nv_c + 6i + 6]`` (linear velocity in the world, angular velocity).

Collisions: a prop has contype ``PROP_BIT`` and conaffinity 1, so it bounces off the floor
(contype 1) and passes through the body and through other props; with a racket in the scene an
explicit ``<pair>`` makes it bounce off the racket head, stiffer than the floor contact.

Bounce (measured in MuJoCo C with a 57-g ball; the racket bounce is tested on both backends in
``tests/test_tennis.py``): MuJoCo's default soft contact (time constant 2 dt, damping ratio 1)
rebounds at e ~ 0.05-0.15, so props use the direct
(-stiffness, -damping) form with the damping that gives ``restitution`` (``_solref``). On the
floor (a half-space) stiffness 5000 rebounds at 0.74-0.76 from 2 to 12 m/s for 0.75 and at
0.09-0.26 for 0 (the juggling balls), at 120 and 240 Hz; a landing ball sinks 0.2-5 cm into this
soft floor (at 120 Hz, 1e4 and more gain energy on landing). A thin
racket head needs 1e5 and 240 Hz: at 120 Hz every setting tried (stiffness 2e3-1e5, time constant
2 dt with damping ratio 0.2-1, heads 1.6-8 cm thick) let the ball through or threw it back
faster than it came; at 240 Hz with a 4-cm head, 1e5 rebounds at 0.75 from 2 to 20 m/s (30 m/s
passes through).

Where a racket is in the scene, each prop gets a force channel (``arena.Channel``: the normal force
of its contact with the racket head, the maximum over the control step's substeps), which the
physics backends report with every step (``Physics.step_forces``).

The task moves its props (a new ball, ``Task.place``) by writing their ``qpos``/``qvel`` between
control steps and reads them after each step (``Task.sense``); ``envs/humanoid.py`` does both.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from typing import Annotated

import jax
import mujoco
import numpy as np
from flax import struct

from jaxmotion.config.checks import Min, NonEmpty, Range
from jaxmotion.physics.character import PROP_BIT, build_mjcf


@dataclasses.dataclass(frozen=True)
class PropConfig:
    """A free sphere in the scene (defaults: a tennis ball)."""

    name: Annotated[str, NonEmpty()] = "ball"
    radius: Annotated[float, Min(0, open=True)] = 0.033
    mass: Annotated[float, Min(0, open=True)] = 0.057
    restitution: Annotated[float, Range(0, 1)] = 0.75
    """Bounce of its contacts: the ratio of outgoing to incoming normal speed MuJoCo's soft
    contact aims at (solref's negative damping form, ``_solref``); a tennis ball off a racket or
    a hard court is about 0.75."""
    rgba: Annotated[tuple[float, float, float, float], Range(0, 1)] = (0.85, 0.95, 0.2, 1.0)


@struct.dataclass
class Props:
    """The props of one scene: ``qpos`` [P, 7] (position, quaternion w-x-y-z), ``qvel`` [P, 6]
    (world linear velocity, angular velocity) and ``force`` [P] or [0], each prop's largest
    normal force against the racket head over the last control step (N; empty without a racket)."""

    qpos: jax.Array
    qvel: jax.Array
    force: jax.Array


def _solref(restitution: float, stiffness: float) -> str:
    """MuJoCo's direct solref (-stiffness, -damping) of a contact that rebounds at
    ``restitution``: a unit-mass spring-damper with e = exp(-zeta pi / sqrt(1 - zeta^2)), damping
    2 zeta sqrt(stiffness) (see the module docstring for what was measured)."""
    e = float(np.clip(restitution, 1e-3, 0.999))
    zeta = -np.log(e) / np.sqrt(np.pi**2 + np.log(e) ** 2)
    return f"{-stiffness:g} {-2 * zeta * np.sqrt(stiffness):g}"


FLOOR_STIFFNESS = 5000.0
RACKET_STIFFNESS = 1e5


def scene_mjcf(
    sword_shield: bool = False, racket: bool = False, props: tuple[PropConfig, ...] = (), floor: bool = True
) -> str:
    """The MJCF of the character (``build_mjcf``) with ``props`` appended to the world body, each
    resting on the floor 1 m apart at x = 50 m until its task places it."""
    xml = build_mjcf(sword_shield, floor=floor, racket=racket)
    if not props:
        return xml
    root = ET.fromstring(xml)
    world = root.find("worldbody")
    names = [p.name for p in props]
    if len(set(names)) != len(names):
        raise ValueError(f"prop names must be unique: {names}")
    for i, p in enumerate(props):
        body = ET.SubElement(world, "body", name=p.name, pos=f"50 {i:g} {p.radius:g}")
        ET.SubElement(body, "freejoint", name=f"{p.name}_free")
        ET.SubElement(
            body,
            "geom",
            name=p.name,
            type="sphere",
            size=f"{p.radius:g}",
            mass=f"{p.mass:g}",
            contype=str(PROP_BIT),
            conaffinity="1",
            condim="3",
            friction="0.6 0.005 0.0001",
            solref=_solref(p.restitution, FLOOR_STIFFNESS),
            solimp="0.95 0.99 0.001",
            rgba=" ".join(f"{c:g}" for c in p.rgba),
        )
    if racket:
        contact = root.find("contact")
        if contact is None:
            contact = ET.SubElement(root, "contact")
        for p in props:
            ET.SubElement(
                contact,
                "pair",
                geom1="racket_head",
                geom2=p.name,
                condim="3",
                friction="0.6 0.6 0.005 0.0001 0.0001",
                solimp="0.95 0.99 0.001",
                solref=_solref(p.restitution, RACKET_STIFFNESS),
            )
    return ET.tostring(root, encoding="unicode")


def prop_channels(m: mujoco.MjModel, props: tuple[PropConfig, ...]) -> tuple:
    """One force channel per prop: its contact with the racket head (none without a racket)."""
    from jaxmotion.physics.arena import Channel

    head = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "racket_head")
    if head < 0:
        return ()
    return tuple(
        Channel(f"{p.name}_racket", ((head, mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, p.name)),)) for p in props
    )
