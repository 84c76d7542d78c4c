"""A tracker of ten short clips of the training split (walks, a run, punches, a kick, a dance, a jump
and a jumping jack; 17 s of motion), resets picking clips uniformly: the CPU-sized step between
``track/small``'s three clips and ``track/all``'s 80. Evaluate on its own clips with
``python -m jaxmotion.eval <run>`` and on clips it never saw with ``--clips``.

Measured on the 2-core CPU (MuJoCo C, seed 0, 2026-12-06; README "Motion tracking"): untrained
1/10 training clips tracked from t = 0 (g-MPJPE 143 mm on it); 8.19M samples (2000 iterations,
60 min sharing the cores) 4/10, the four walks, g-MPJPE 74 mm, MPJPE 48 mm; 16.4M (4000) 5/10
(+ the kick), 81 / 60 mm, 3/10 at ``--noise 0.25``, 0/10 at ``--noise 1``; on the 15 dev clips
0/15 untrained and at 8.19M, 1/15 at 16.4M. Run, punch, dance_a, jump and the jumping jack stay
hard."""

from _common import track

MEDIUM = tuple("deepmimic/humanoid3d_" + n + ".txt" for n in ("walk", "run", "punch", "kick", "dance_a", "jump")) + tuple(
    "compositemotion/" + n + ".json" for n in ("gym/chest_open+walk_in_place", "gym/front_jumping_jack",
                                               "iccgan/joyful_walk", "iccgan/stoop_walk"))


def config():
    return track(MEDIUM, iterations=4000, init_sampling="uniform")
