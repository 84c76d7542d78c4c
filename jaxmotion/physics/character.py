"""The jaxmotion humanoid: one table of bodies, joints and geoms, written out as MJCF.

The 15-body, 28-hinge humanoid is the DeepMimic ``humanoid3d`` / Isaac Gym ``amp_humanoid`` that
every shared clip uses; dimensions, masses (densities), joint ranges and PD gains follow
``shared/models/compositemotion/humanoid.xml``. The sword-and-shield variant (17 bodies, 31 hinges)
adds a 3-DoF right wrist, a sword on the right hand and a shield on the left forearm, as in ASE's
``amp_humanoid_sword_shield.xml``; it is built from the same table.

Choices (see ``physics/sim.py`` for the solver settings):

* The PD servo is written as MuJoCo actuators: fixed gain ``kp``, affine bias ``-kp*q - kd*qdot``,
  and ``forcerange`` = the motor's torque limit (its ``gear`` in the source model, which Isaac Gym
  uses as the drive's effort limit). With the ``implicitfast`` integrator the damping term is
  integrated implicitly, which is what keeps the character standing at 120 Hz; an explicit PD
  at the same gains does not (DESIGN.md, measured facts).
* Joint ``stiffness``/``damping`` of the source are PD gains, not springs, so our joints carry
  no passive stiffness; armature is kept.
* The hips' three hinges come in y, x, z order (flexion first), not the source's x, y, z. With
  x, y, z the chain is singular at 90 degrees of hip flexion (the x and z axes line up), which
  every squat, lunge and crouch passes through: the shared squat then needs hip angles 40-76
  degrees outside the joint ranges in 75% of its frames, while decomposed flexion-first it stays
  within them up to 5 (right hip flexion) and 17 degrees (right hip twist). The singularity moves
  to 90 degrees of abduction, which no clip reaches. Isaac Gym, the authors' simulator, treats
  the three hinges as one spherical joint, so the order is our modelling choice there too.
* Bodies collide with the floor only (``contype``/``conaffinity`` bits): 34 contact candidates
  instead of 175, several times cheaper in MJX.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence

import mujoco
import numpy as np

# Geom tuples: (name, type, attributes) where attributes is the MJCF attribute string.
_G = tuple[str, str, str]


@dataclasses.dataclass(frozen=True)
class JointSpec:
    """One hinge: name, axis index (0=x, 1=y, 2=z), range in degrees, PD gains and torque limit."""

    name: str
    axis: int
    range_deg: tuple[float, float]
    kp: float
    kd: float
    max_torque: float
    armature: float


@dataclasses.dataclass(frozen=True)
class BodySpec:
    """One rigid body: its parent, offset in the parent, hinges and collision/visual geoms."""

    name: str
    parent: str | None
    pos: tuple[float, float, float]
    joints: tuple[JointSpec, ...]
    geoms: tuple[_G, ...]


def _hinges(
    prefix: str,
    axes: str,
    lo_hi: Sequence[tuple[float, float]],
    kp: float,
    kd: float,
    torque: float,
    armature: float,
    single: bool = False,
) -> tuple[JointSpec, ...]:
    out = []
    for ax, rng in zip(axes, lo_hi):
        name = prefix if single else f"{prefix}_{ax}"
        out.append(JointSpec(name, "xyz".index(ax), rng, kp, kd, torque, armature))
    return tuple(out)


# Props (``physics/props.py``) have this contype bit, which no body geom's conaffinity has (they
# have bit 1, the floor's contype): a ball passes through the character but bounces off the floor.
PROP_BIT = 2


def _body_table(sword_shield: bool, racket: bool = False) -> list[BodySpec]:
    cap = "capsule"
    bodies = [
        BodySpec(
            "pelvis",
            None,
            (0, 0, 1),
            (),
            (
                ("pelvis", "sphere", 'pos="0 0 0.07" size=".09" density="2226"'),
                ("upper_waist", "sphere", 'pos="0 0 0.205" size="0.07" density="2226"'),
            ),
        ),
        BodySpec(
            "torso",
            "pelvis",
            (0, 0, 0.236151),
            _hinges("abdomen", "xyz", [(-60, 60), (-60, 90), (-50, 50)], 600, 60, 125, 0.025),
            (
                ("torso", "sphere", 'pos="0 0 0.12" size="0.11" density="1794"'),
                (
                    "right_clavicle",
                    cap,
                    'fromto="-0.0060125 -0.0457775 0.2287955 -0.016835 -0.128177 0.2376182" size=".045" density="1100"',
                ),
                (
                    "left_clavicle",
                    cap,
                    'fromto="-0.0060125 0.0457775 0.2287955 -0.016835 0.128177 0.2376182" size=".045" density="1100"',
                ),
            ),
        ),
        BodySpec(
            "head",
            "torso",
            (0, 0, 0.223894),
            _hinges("neck", "xyz", [(-50, 50), (-40, 60), (-45, 45)], 50, 5, 20, 0.017),
            (("head", "sphere", 'pos="0 0 0.175" size="0.095" density="1081"'),),
        ),
    ]
    for side, sgn in (("right", -1), ("left", 1)):
        sx = [(-180, 45), (-180, 60), (-90, 90)] if side == "right" else [(-45, 180), (-180, 60), (-90, 90)]
        arm = [
            BodySpec(
                f"{side}_upper_arm",
                "torso",
                (-0.02405, sgn * 0.18311, 0.24350),
                _hinges(f"{side}_shoulder", "xyz", sx, 200, 20, 70, 0.02),
                ((f"{side}_upper_arm", cap, 'fromto="0 0 -0.05 0 0 -0.23" size=".045" density="982"'),),
            ),
            BodySpec(
                f"{side}_lower_arm",
                f"{side}_upper_arm",
                (0, 0, -0.274788),
                _hinges(f"{side}_elbow", "y", [(-160, 0)], 150, 15, 60, 0.015, single=True),
                ((f"{side}_lower_arm", cap, 'fromto="0 0 -0.0525 0 0 -0.1875" size="0.04" density="1056"'),),
            ),
        ]
        wrist = ()
        if sword_shield and side == "right":
            wrist = _hinges("right_hand", "xyz", [(-90, 90)] * 3, 100, 10, 50, 0.003)
        hand = BodySpec(
            f"{side}_hand",
            f"{side}_lower_arm",
            (0, 0, -0.258947),
            wrist,
            ((f"{side}_hand", "sphere", 'size=".04" density="1865"'),),
        )
        arm.append(hand)
        if sword_shield and side == "right" and racket:
            # A tennis racket in the sword's place (the body keeps the clips' name "sword"): a
            # 0.32-m handle from the hand and a 0.32 x 0.25 m head whose face is normal to the
            # sword's cutting edge (z), 0.31 kg in all. The head is 4 cm thick, a collision proxy:
            # a ball struck at up to 20 m/s moves 8 cm per 240-Hz substep and would pass through
            # a real racket's 2 cm (physics/props.py). Balls meet it through explicit pairs.
            arm.append(
                BodySpec(
                    "sword",
                    "right_hand",
                    (0.74, 0, 0),
                    (),
                    (
                        ("racket_handle", cap, 'fromto="-0.87 0 0 -0.55 0 0" size="0.016" density="450"'),
                        (
                            "racket_head",
                            "box",
                            f'pos="{RACKET_HEAD[0]:g} 0 0" size="0.16 0.125 0.02" density="65" rgba="0.2 0.7 0.3 1"',
                        ),
                    ),
                )
            )
        elif sword_shield and side == "right":
            arm.append(
                BodySpec(
                    "sword",
                    "right_hand",
                    (0.74, 0, 0),
                    (),
                    (
                        ("sword_hilt", cap, 'fromto="-0.87 0 0 -0.64 0 0" size="0.023" density="300"'),
                        ("sword_blade", "box", 'pos="-0.34 0 0" size="0.34 0.01 0.035" density="600"'),
                    ),
                )
            )
        if sword_shield and side == "left":
            # Ordered as in the ASE clips: the shield comes before the left hand. With the racket
            # the shield body stays (the clips move it) but weighs 4 g and touches nothing.
            shield = (("shield", "cylinder", 'fromto="0 0 0 0 0.03 0" size="0.3" density="250"'),)
            if racket:
                shield = (("shield", "sphere", 'size="0.01" density="1000" conaffinity="0" rgba="0 0 0 0"'),)
            arm.insert(2, BodySpec("shield", "left_lower_arm", (0, 0.07, -0.12), (), shield))
        bodies += arm
    for side, sgn in (("right", -1), ("left", 1)):
        # Hip hinges in y, x, z order (flexion, then abduction, then twist); ranges as the source.
        hx = [(-140, 60), (-60, 15), (-60, 35)] if side == "right" else [(-140, 60), (-15, 60), (-35, 60)]
        bodies += [
            BodySpec(
                f"{side}_thigh",
                "pelvis",
                (0, sgn * 0.084887, 0),
                _hinges(f"{side}_hip", "yxz", hx, 300, 30, 125, 0.02),
                ((f"{side}_thigh", cap, 'fromto="0 0 -0.06 0 0 -0.36" size="0.055" density="1269"'),),
            ),
            BodySpec(
                f"{side}_shin",
                f"{side}_thigh",
                (0, 0, -0.421546),
                _hinges(f"{side}_knee", "y", [(0, 160)], 300, 30, 100, 0.02, single=True),
                ((f"{side}_shin", cap, 'fromto="0 0 -0.045 0 0 -0.355" size=".05" density="1014"'),),
            ),
            BodySpec(
                f"{side}_foot",
                f"{side}_shin",
                (0, 0, -0.409870),
                _hinges(f"{side}_ankle", "xyz", [(-30, 30), (-55, 55), (-40, 40)], 200, 20, 50, 0.01),
                ((f"{side}_foot", "box", 'pos="0.045 0 -0.0225" size="0.0885 0.045 0.0275" density="1141"'),),
            ),
        ]
    return bodies


# Per-group colours for rendering (RGBA); link colouring by body group is done at render time.
_BODY_RGBA = "0.8 0.6 0.4 1"


def _fmt(v: Sequence[float]) -> str:
    return " ".join(f"{x:g}" for x in v)


def _write_body(b: BodySpec, children: dict[str, list[BodySpec]], indent: int) -> list[str]:
    pad = "  " * indent
    lines = [f'{pad}<body name="{b.name}" pos="{_fmt(b.pos)}">']
    if b.parent is None:
        lines.append(f'{pad}  <freejoint name="root"/>')
    for j in b.joints:
        axis = ["1 0 0", "0 1 0", "0 0 1"][j.axis]
        lines.append(
            f'{pad}  <joint name="{j.name}" axis="{axis}" range="{_fmt(j.range_deg)}" armature="{j.armature:g}"/>'
        )
    for name, typ, attrs in b.geoms:
        lines.append(f'{pad}  <geom name="{name}" type="{typ}" {attrs}/>')
    for c in children.get(b.name, []):
        lines += _write_body(c, children, indent + 1)
    lines.append(f"{pad}</body>")
    return lines


# The racket head's centre in the "sword" body's frame.
RACKET_HEAD = (-0.39, 0.0, 0.0)


def build_mjcf(sword_shield: bool = False, floor: bool = True, racket: bool = False) -> str:
    """Returns the MJCF text of the humanoid (optionally with sword and shield; ``racket``: a
    tennis racket instead of the sword, and no shield) over a floor."""
    if racket and not sword_shield:
        raise ValueError(
            "the racket needs the sword-and-shield character (its 3-DoF wrist): set env.physics.sword_shield=true"
        )
    bodies = _body_table(sword_shield, racket)
    children: dict[str, list[BodySpec]] = {}
    for b in bodies:
        if b.parent is not None:
            children.setdefault(b.parent, []).append(b)
    joints = [j for b in bodies for j in b.joints]
    out = [
        f'<mujoco model="jaxmotion_humanoid{"_sword_shield" if sword_shield else ""}">',
        '  <compiler angle="degree"/>',
        # Solver settings are set again in physics/sim.py; these make MuJoCo C match MJX.
        '  <option timestep="0.008333333333333333" integrator="implicitfast" iterations="16" '
        'ls_iterations="16" solver="Newton">',
        '    <flag eulerdamp="disable"/>',
        "  </option>",
        '  <visual><global offwidth="1280" offheight="720"/></visual>',
        "  <asset>",
        '    <texture name="grid" type="2d" builtin="checker" rgb1=".2 .3 .4" rgb2=".1 .15 .2" '
        'width="512" height="512"/>',
        '    <material name="grid" texture="grid" texrepeat="1 1" texuniform="true" reflectance=".1"/>',
        "  </asset>",
        "  <default>",
        # Body geoms collide with the floor only: contype 0 & conaffinity 1 against floor 1/0.
        f'    <geom contype="0" conaffinity="1" condim="3" friction="1 0.05 0.05" '
        f'solimp=".9 .99 .003" solref=".015 1" rgba="{_BODY_RGBA}"/>',
        '    <joint type="hinge" limited="true" solimplimit="0 .99 .01"/>',
        "  </default>",
        "  <worldbody>",
    ]
    if floor:
        out.append(
            '    <geom name="floor" type="plane" size="100 100 .2" material="grid" '
            'contype="1" conaffinity="0" condim="3" rgba="1 1 1 1"/>'
        )
    out.append('    <light name="top" pos="0 0 4" mode="trackcom" diffuse=".8 .8 .8"/>')
    out += _write_body(bodies[0], children, 2)
    out.append("  </worldbody>")
    out.append("  <actuator>")
    for j in joints:
        out.append(
            f'    <general name="{j.name}" joint="{j.name}" gaintype="fixed" gainprm="{j.kp:g}" '
            f'biastype="affine" biasprm="0 {-j.kp:g} {-j.kd:g}" forcelimited="true" '
            f'forcerange="{-j.max_torque:g} {j.max_torque:g}" ctrllimited="false"/>'
        )
    out.append("  </actuator>")
    out.append("</mujoco>")
    return "\n".join(out)


@dataclasses.dataclass(frozen=True)
class Character:
    """Static facts about a character that the motion, env and eval layers share (numpy only)."""

    sword_shield: bool
    body_names: tuple[str, ...]
    parents: tuple[int, ...]
    joint_names: tuple[str, ...]
    # For each hinge: index of its body, axis index (0,1,2).
    joint_body: tuple[int, ...]
    joint_axis: tuple[int, ...]
    joint_range: np.ndarray  # [n_dof, 2] radians
    kp: np.ndarray
    kd: np.ndarray
    max_torque: np.ndarray
    body_offsets: np.ndarray  # [n_bodies, 3] in the parent frame

    @property
    def num_bodies(self) -> int:
        return len(self.body_names)

    @property
    def num_dof(self) -> int:
        return len(self.joint_names)

    def body_index(self, name: str) -> int:
        """Index of a body by name; a clear error lists the valid names otherwise."""
        try:
            return self.body_names.index(name)
        except ValueError:
            raise KeyError(f"character has no body {name!r}; bodies are {list(self.body_names)}") from None

    def body_joints(self, body: int) -> list[int]:
        """The DoF indices (in qpos[7:] order) of a body's hinges, in their chain order."""
        return [i for i, b in enumerate(self.joint_body) if b == body]

    def mj_model(self) -> mujoco.MjModel:
        """A fresh MuJoCo model of this character (not cached: callers may edit it)."""
        return mujoco.MjModel.from_xml_string(build_mjcf(self.sword_shield))


@functools.cache
def character(sword_shield: bool = False) -> Character:
    """The humanoid (15 bodies, 28 hinges), or with sword and shield (17 bodies, 31 hinges)."""
    bodies = _body_table(sword_shield)
    names = tuple(b.name for b in bodies)
    parents = tuple(-1 if b.parent is None else names.index(b.parent) for b in bodies)
    jb, ja, rng, kp, kd, tq, jn = [], [], [], [], [], [], []
    for i, b in enumerate(bodies):
        for j in b.joints:
            jn.append(j.name)
            jb.append(i)
            ja.append(j.axis)
            rng.append(np.deg2rad(j.range_deg))
            kp.append(j.kp)
            kd.append(j.kd)
            tq.append(j.max_torque)
    ch = Character(
        sword_shield=sword_shield,
        body_names=names,
        parents=parents,
        joint_names=tuple(jn),
        joint_body=tuple(jb),
        joint_axis=tuple(ja),
        joint_range=np.array(rng, np.float64),
        kp=np.array(kp),
        kd=np.array(kd),
        max_torque=np.array(tq),
        body_offsets=np.array([b.pos for b in bodies], np.float64),
    )
    m = ch.mj_model()
    # The table and the compiled model must agree on order (MuJoCo orders bodies depth-first).
    assert tuple(m.body(i + 1).name for i in range(m.nbody - 1)) == names, "body order mismatch"
    assert m.nu == ch.num_dof and m.nq == 7 + ch.num_dof
    return ch
