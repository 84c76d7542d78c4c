"""A tracker of ten short clips of the training split (walks, a run, punches, a kick, a dance, a jump
and a jumping jack; 17 s of motion), resets picking clips uniformly: the CPU-sized step between
``track/small``'s three clips and ``track/all``'s 80. Evaluate on its own clips with
``python -m jaxmotion.eval <run>`` and on clips it never saw with ``--clips``.
Results: docs/tracker.md, "Ten clips on a CPU".
"""

from _common import track

MEDIUM = tuple(
    "deepmimic/humanoid3d_" + n + ".txt" for n in ("walk", "run", "punch", "kick", "dance_a", "jump")
) + tuple(
    "compositemotion/" + n + ".json"
    for n in ("gym/chest_open+walk_in_place", "gym/front_jumping_jack", "iccgan/joyful_walk", "iccgan/stoop_walk")
)


def config():
    return track(MEDIUM, iterations=4000, init_sampling="uniform")
