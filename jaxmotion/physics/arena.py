"""Two characters in one MuJoCo model: the boxing ring and the fencing piste (Won et al. 2021).

``arena_mjcf(cfg)`` writes one MJCF with two copies of the character, every body, joint, geom and
actuator prefixed ``p0_`` / ``p1_`` (player 0's qpos first). Choices (notes won2021.md §1):

* **Contacts as explicit pairs.** Body geoms still collide with the floor (and the ropes) through
  their ``contype``/``conaffinity`` bits; between the players only the listed ``<pair>``s exist:
  scoring pairs (gloves vs the opponent's head, chest and belly; the blade vs the opponent's
  torso), blocks (arms vs arms, blade vs blade and shield), clinches (trunk vs trunk, thigh vs
  thigh) and arms against the opponent's trunk. MJX's collision cost grows with every candidate
  pair, so the list is short; self-collision is off, as for the single character.
* **Gloves**: the hand spheres enlarged to r = 0.06 m at 0.5 kg (boxing).
* **Ropes**: four static boxes 0.2 m thick, 0.25-1.25 m above the floor, around a 5 m inner
  square; the piste has no geometry (its 12 m x 2 m bounds are a rule of the fencing task).
* **Force channels**: the normal force of every scoring contact, summed per attacker, is read on
  every physics substep and its maximum over the control step reported (``Channel``; MuJoCo C by
  contact sensors, MJX from the constraint forces), so a punch that lasts one substep counts.
  Both agree with ``mj_contactForce`` (``tests/test_bout.py``).

Calibration (``tests/test_bout.py::test_scripted_punch_and_thrust_always_register_a_touch``,
2026-12-02): player 0 lunges with the arm straight ahead (the blade along it for fencing), its
glove at 8 m/s or blade tip at 10 m/s, from 10 cm at player 1's chest, centrally or 4 cm off.
At 120, 240 and 480 Hz every lunge registers in its first control step, with peak normal forces
of 5.8-7.9 kN (glove) and 4.7-8.5 kN (blade), far above the 1-N touch threshold, and the 200-N
damage clip always saturates. These are whole-body lunges (49 kg moving). An arm-only punch
(``test_scripted_arm_only_punch_registers_a_touch``, 2026-12-04: the body still, shoulder and
elbow driven so that the glove moves at the given speed, PD targets leading the pose by 0.1 s)
peaks at 1.1-1.5 kN at 8 m/s (every rate, centrally or 4 cm off: the clip saturates), 0.5-0.6
kN at 4 m/s and 170-220 N at 2 m/s; at 1 m/s the servo stops the arm before it arrives.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import xml.etree.ElementTree as ET
from typing import Annotated, Literal

import mujoco
import numpy as np

from jaxmotion.config.checks import Min, Ordered
from jaxmotion.config.errors import ConfigError
from jaxmotion.physics.character import build_mjcf, character

PREFIXES = ("p0_", "p1_")
PLAYER_RGBA = ("0.80 0.35 0.30 1", "0.30 0.45 0.80 1")
ROPE_RGBA = "0.9 0.9 0.85 1"


@dataclasses.dataclass(frozen=True)
class ArenaConfig:
    """Geometry of the two-player scene."""

    sport: Literal["boxing", "fencing"] = "boxing"
    """'boxing' (15-body humanoids with gloves, a roped ring) or 'fencing' (sword-and-shield
    characters, no ropes): the names of ``SPORTS``."""
    ring_size: Annotated[float, Min(0)] = 5.0
    """Boxing: side of the square inside the ropes (m); 0: no ropes."""
    rope_thickness: Annotated[float, Min(0, open=True)] = 0.2
    rope_height: Annotated[tuple[float, float], Min(0), Ordered(strict=True)] = (0.25, 1.25)
    glove_radius: Annotated[float, Min(0, open=True)] = 0.06
    glove_mass: Annotated[float, Min(0, open=True)] = 0.5
    pair_condim: Literal[1, 3, 4, 6] = 3
    """condim of the player-player pairs (3: friction cone; 1: frictionless; MuJoCo's 1, 3, 4 or 6)."""

    def __post_init__(self):
        if self.sport not in SPORTS:  # made in Python (overrides: the Literal)
            raise ConfigError(f"arena sport {self.sport!r} is not one of {sorted(SPORTS)}")


@dataclasses.dataclass(frozen=True)
class SportGeoms:
    """Which geoms score on which, per sport (names without the player prefix)."""

    sword_shield: bool
    scorers: tuple[str, ...]
    targets: tuple[str, ...]
    blocks: tuple[tuple[tuple[str, ...], tuple[str, ...]], ...]
    """(own geoms, opponent geoms) sets whose pairs are physical but never score."""
    scorer_points: tuple[tuple[str, tuple[float, float, float]], ...]
    """(body, offset in the body frame) of the points that hit: glove centres, blade points."""
    target_points: tuple[tuple[str, tuple[float, float, float]], ...]
    """(body, offset) of the target centres (head, chest, belly; the fencer's torso)."""


_TRUNK = ("torso", "upper_waist", "pelvis")
_ARMS = ("right_hand", "left_hand", "right_lower_arm", "left_lower_arm")
SPORTS = {
    "boxing": SportGeoms(
        sword_shield=False,
        scorers=("right_hand", "left_hand"),
        targets=("head", "torso", "right_clavicle", "left_clavicle", "upper_waist"),
        blocks=(
            (_ARMS, _ARMS + ("right_upper_arm", "left_upper_arm")),
            (("right_lower_arm", "left_lower_arm"), ("head", "torso", "upper_waist")),
            (_TRUNK, _TRUNK),
            (("right_thigh", "left_thigh"), ("right_thigh", "left_thigh")),
        ),
        scorer_points=(("right_hand", (0.0, 0.0, 0.0)), ("left_hand", (0.0, 0.0, 0.0))),
        target_points=(("head", (0.0, 0.0, 0.175)), ("torso", (0.0, 0.0, 0.12)), ("pelvis", (0.0, 0.0, 0.205))),
    ),
    "fencing": SportGeoms(
        sword_shield=True,
        scorers=("sword_blade",),
        targets=("torso", "right_clavicle", "left_clavicle", "upper_waist"),
        blocks=(
            (
                ("sword_blade",),
                (
                    "sword_blade",
                    "shield_plate",
                    "head",
                    "right_upper_arm",
                    "left_upper_arm",
                    "right_lower_arm",
                    "left_lower_arm",
                    "right_hand",
                    "left_hand",
                    "right_thigh",
                    "left_thigh",
                    "pelvis",
                ),
            ),
            (("shield_plate",), ("shield_plate",)),
            (_TRUNK, _TRUNK),
        ),
        # The blade's tip is the sword body's origin; the blade runs 0.68 m back along -x.
        scorer_points=(("sword", (0.0, 0.0, 0.0)), ("sword", (-0.2, 0.0, 0.0)), ("sword", (-0.4, 0.0, 0.0))),
        target_points=(("torso", (0.0, 0.0, 0.12)), ("pelvis", (0.0, 0.0, 0.205))),
    ),
}


@dataclasses.dataclass(frozen=True)
class Channel:
    """A force channel: the geom-id pairs whose contact normal forces are summed."""

    name: str
    pairs: tuple[tuple[int, int], ...]


def _prefix_tree(body: ET.Element, prefix: str, rgba: str) -> ET.Element:
    b = copy.deepcopy(body)
    for el in b.iter():
        if "name" in el.attrib:
            el.set("name", prefix + el.get("name"))
        if el.tag == "geom" and "rgba" not in el.attrib:
            el.set("rgba", rgba)
    return b


def _unique_pairs(sets, a: str, b: str) -> list[tuple[str, str]]:
    """Name pairs (player a's geom, player b's geom) of every (own, opponent) set, both ways."""
    out = []
    for own, opp in sets:
        for x in own:
            for y in opp:
                for p, q in ((a + x, b + y), (b + x, a + y)):
                    if (p, q) not in out and (q, p) not in out:
                        out.append((p, q))
    return out


def scoring_pairs(cfg: ArenaConfig, attacker: int) -> list[tuple[str, str]]:
    """(attacker's scorer geom, defender's target geom) name pairs."""
    sp = SPORTS[cfg.sport]
    a, d = PREFIXES[attacker], PREFIXES[1 - attacker]
    return [(a + s, d + t) for s in sp.scorers for t in sp.targets]


def arena_mjcf(cfg: ArenaConfig) -> str:
    """The MJCF text of the two-player scene (see the module docstring)."""
    sp = SPORTS[cfg.sport]
    root = ET.fromstring(build_mjcf(sp.sword_shield))
    root.set("model", f"jaxmotion_{cfg.sport}")
    wb = root.find("worldbody")
    body = next(b for b in wb if b.tag == "body")
    wb.remove(body)
    if cfg.sport == "boxing":
        # Gloves: the hand spheres enlarged, density lowered to keep the mass.
        vol = 4.0 / 3.0 * np.pi * cfg.glove_radius**3
        for g in body.iter("geom"):
            if g.get("name") in ("right_hand", "left_hand"):
                g.set("size", f"{cfg.glove_radius:g}")
                g.set("density", f"{cfg.glove_mass / vol:g}")
    if sp.sword_shield:
        # MJX has no cylinder-box collision: the shield meets blades and shields through a
        # massless, invisible box of its size (the cylinder still meets the floor).
        for b in body.iter("body"):
            if b.get("name") == "shield":
                ET.SubElement(
                    b,
                    "geom",
                    name="shield_plate",
                    type="box",
                    pos="0 0.015 0",
                    size="0.3 0.015 0.3",
                    mass="0",
                    rgba="0 0 0 0",
                    contype="0",
                    conaffinity="0",
                )
    for k, (prefix, rgba) in enumerate(zip(PREFIXES, PLAYER_RGBA)):
        p = _prefix_tree(body, prefix, rgba)
        p.set("pos", f"{2 * k - 1:g} 0 1")
        wb.append(p)
    if cfg.sport == "boxing" and cfg.ring_size > 0:
        h, t = cfg.ring_size / 2, cfg.rope_thickness
        lo, hi = cfg.rope_height
        zc, zh = (lo + hi) / 2, (hi - lo) / 2
        for i, (x, y, sx, sy) in enumerate(
            [
                (h + t / 2, 0, t / 2, h + t),
                (-h - t / 2, 0, t / 2, h + t),
                (0, h + t / 2, h + t, t / 2),
                (0, -h - t / 2, h + t, t / 2),
            ]
        ):
            ET.SubElement(
                wb,
                "geom",
                name=f"rope{i}",
                type="box",
                pos=f"{x:g} {y:g} {zc:g}",
                size=f"{sx:g} {sy:g} {zh:g}",
                contype="1",
                conaffinity="0",
                condim="3",
                rgba=ROPE_RGBA,
            )
    contact = ET.SubElement(root, "contact")
    pairs = scoring_pairs(cfg, 0) + scoring_pairs(cfg, 1) + _unique_pairs(sp.blocks, PREFIXES[0], PREFIXES[1])
    for g1, g2 in pairs:
        ET.SubElement(
            contact,
            "pair",
            geom1=g1,
            geom2=g2,
            condim=str(cfg.pair_condim),
            friction="0.5 0.5 0.005 0.0001 0.0001",
            solref=".015 1",
            solimp=".9 .99 .003",
        )
    act = root.find("actuator")
    gens = list(act)
    for g in gens:
        act.remove(g)
    for prefix in PREFIXES:
        for g in gens:
            e = copy.deepcopy(g)
            e.set("name", prefix + g.get("name"))
            e.set("joint", prefix + g.get("joint"))
            act.append(e)
    return ET.tostring(root, encoding="unicode")


@functools.lru_cache(maxsize=8)
def arena_model(cfg: ArenaConfig) -> mujoco.MjModel:
    """The compiled two-player model (cached; copy before editing)."""
    return mujoco.MjModel.from_xml_string(arena_mjcf(cfg))


def channels(cfg: ArenaConfig, m: mujoco.MjModel | None = None) -> tuple[Channel, ...]:
    """The scoring force channels: player 0's hits on player 1, then player 1's on player 0."""
    m = arena_model(cfg) if m is None else m
    gid = lambda n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n)
    return tuple(Channel(f"p{k}_scores", tuple((gid(a), gid(b)) for a, b in scoring_pairs(cfg, k))) for k in range(2))


@dataclasses.dataclass(frozen=True)
class Layout:
    """Where each player's pieces sit in the two-player model."""

    nq: int
    nv: int
    nu: int
    nb: int

    def qpos(self, k: int) -> slice:
        return slice(k * self.nq, (k + 1) * self.nq)

    def qvel(self, k: int) -> slice:
        return slice(k * self.nv, (k + 1) * self.nv)

    def bodies(self, k: int) -> slice:
        """Body indices in the model (world = 0) of player k."""
        return slice(1 + k * self.nb, 1 + (k + 1) * self.nb)


def layout(cfg: ArenaConfig) -> Layout:
    ch = character(SPORTS[cfg.sport].sword_shield)
    m = arena_model(cfg)
    lay = Layout(nq=7 + ch.num_dof, nv=6 + ch.num_dof, nu=ch.num_dof, nb=ch.num_bodies)
    assert m.nq == 2 * lay.nq and m.nv == 2 * lay.nv and m.nu == 2 * lay.nu and m.nbody == 1 + 2 * lay.nb
    for k, prefix in enumerate(PREFIXES):
        names = [m.body(i).name for i in range(*lay.bodies(k).indices(m.nbody))]
        assert names == [prefix + n for n in ch.body_names], "unexpected body order"
    return lay


def scenery(cfg: ArenaConfig, piste: tuple[float, float] | None = None) -> tuple[dict, ...]:
    """Visual-only geoms of the scene for the renderer: the ropes, or the piste's edges (thin
    strips on the floor) when ``piste`` (length, width) is given. Dicts of MJCF geom attributes."""
    out = []
    if cfg.sport == "boxing" and cfg.ring_size > 0:
        m = arena_model(cfg)
        for i in range(4):
            g = m.geom(f"rope{i}")
            out.append(
                {
                    "name": f"scenery_rope{i}",
                    "type": "box",
                    "pos": _fmt3(g.pos),
                    "size": _fmt3(g.size),
                    "rgba": ROPE_RGBA,
                }
            )
    if piste is not None:
        L, W = piste
        for i, (x, y, sx, sy) in enumerate(
            [(0, W / 2, L / 2, 0.02), (0, -W / 2, L / 2, 0.02), (L / 2, 0, 0.02, W / 2), (-L / 2, 0, 0.02, W / 2)]
        ):
            out.append(
                {
                    "name": f"scenery_piste{i}",
                    "type": "box",
                    "pos": f"{x:g} {y:g} 0.002",
                    "size": f"{sx:g} {sy:g} 0.002",
                    "rgba": "0.95 0.95 0.95 1",
                }
            )
    return tuple(out)


def _fmt3(v) -> str:
    return " ".join(f"{float(x):g}" for x in v)
