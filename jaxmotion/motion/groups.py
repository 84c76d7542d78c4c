"""Body groups: which links a (partial-body) imitation task tracks, and in which frame.

A group's ``anchor`` names the body whose frame the group's link poses are expressed in; None
means the character's heading frame (root yaw only, origin = the root projected to z = 0).
"""

from __future__ import annotations

import dataclasses
from typing import Any
from collections.abc import Mapping

import numpy as np

from jaxmotion.physics.character import Character


@dataclasses.dataclass(frozen=True)
class BodyGroup:
    """A named set of links and the anchor frame they are observed in.

    Attributes:
        name: group name.
        links: body names, in the order they are observed.
        anchor: body name, or None for the heading frame.
    """

    name: str
    links: tuple[str, ...]
    anchor: str | None = None


def _arms(ch: Character) -> tuple[str, ...]:
    arm = ("right_upper_arm", "right_lower_arm", "right_hand", "left_upper_arm", "left_lower_arm", "left_hand")
    extra = ("sword", "shield") if ch.sword_shield else ()
    return _in_body_order(ch, arm + extra)


def _legs() -> tuple[str, ...]:
    return ("right_thigh", "right_shin", "right_foot", "left_thigh", "left_shin", "left_foot")


def _in_body_order(ch: Character, names) -> tuple[str, ...]:
    return tuple(sorted(names, key=ch.body_index))


def default_groups(character: Character) -> dict[str, BodyGroup]:
    """The standard groups of a character.

    * ``upper``: torso, head, arms and hands (+ sword, shield), anchor pelvis.
    * ``lower``: pelvis and legs, heading frame.
    * ``arms``: arms and hands (+ sword, shield), anchor torso.
    * ``rest``: torso, head, pelvis and legs, heading frame.
    * ``full``: every body, heading frame.

    Links are listed in the character's body order.

    Args:
        character: the character.

    Returns:
        name -> BodyGroup.
    """
    ch = character
    arms = _arms(ch)
    groups = [
        BodyGroup("upper", _in_body_order(ch, ("torso", "head") + arms), "pelvis"),
        BodyGroup("lower", _in_body_order(ch, ("pelvis",) + _legs()), None),
        BodyGroup("arms", arms, "torso"),
        BodyGroup("rest", _in_body_order(ch, ("pelvis", "torso", "head") + _legs()), None),
        BodyGroup("full", tuple(ch.body_names), None),
    ]
    return {g.name: g for g in groups}


def _check_body(ch: Character, group: str, name: Any, role: str) -> None:
    if not isinstance(name, str) or name not in ch.body_names:
        raise ValueError(f"body group {group!r}: unknown {role} {name!r}; valid bodies are {list(ch.body_names)}")


def resolve_group(spec: str | BodyGroup | Mapping[str, Any], character: Character) -> BodyGroup:
    """A validated ``BodyGroup`` from a default group name, a BodyGroup, or a mapping.

    Args:
        spec: a name from ``default_groups``; a ``BodyGroup``; or a mapping with ``links``
            (list of body names) and optional ``name`` (default "custom") and ``anchor``
            (body name or None, default None).
        character: the character.

    Returns:
        The group.

    Raises:
        ValueError: unknown group name, unknown body (the message lists the valid bodies), empty
            or duplicated links.
    """
    ch = character
    if isinstance(spec, str):
        groups = default_groups(ch)
        if spec not in groups:
            raise ValueError(f"unknown body group {spec!r}; default groups are {list(groups)}")
        return groups[spec]
    if isinstance(spec, Mapping):
        unknown = set(spec) - {"name", "links", "anchor"}
        if unknown or "links" not in spec:
            raise ValueError(
                f"a body group mapping needs 'links' and may have 'name', 'anchor'; got keys {sorted(spec)}"
            )
        links = spec["links"]
        if isinstance(links, str):
            raise ValueError(f"body group links must be a list of body names, got {links!r}")
        spec = BodyGroup(str(spec.get("name", "custom")), tuple(links), spec.get("anchor"))
    if not isinstance(spec, BodyGroup):
        raise ValueError(f"cannot make a body group from {type(spec).__name__}: {spec!r}")
    if not spec.links:
        raise ValueError(f"body group {spec.name!r} has no links")
    for link in spec.links:
        _check_body(ch, spec.name, link, "link")
    if len(set(spec.links)) != len(spec.links):
        raise ValueError(f"body group {spec.name!r} lists a link twice: {list(spec.links)}")
    if spec.anchor is not None:
        _check_body(ch, spec.name, spec.anchor, "anchor")
    return BodyGroup(spec.name, tuple(spec.links), spec.anchor)


def group_indices(group: str | BodyGroup | Mapping[str, Any], character: Character) -> tuple[np.ndarray, int]:
    """Body indices of a group's links and of its anchor.

    Args:
        group: anything ``resolve_group`` accepts.
        character: the character.

    Returns:
        (links [n_links] np.int32 in the group's order, anchor index or -1 for the heading frame).
    """
    ch = character
    g = resolve_group(group, ch)
    links = np.array([ch.body_index(n) for n in g.links], np.int32)
    return links, (-1 if g.anchor is None else ch.body_index(g.anchor))
