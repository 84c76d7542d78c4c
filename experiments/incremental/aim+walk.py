"""Aiming + target location while walking, learned incrementally (paper §5, Eq. 10, §6.5): the
same scene, objectives and ω as `goal/aim+walk`, with the frozen `goal/location_walk` policy as
the meta policy. The new policy outputs μ, σ and a weight w per DoF of the meta policy's sampled
action; it starts as the meta policy (w = 0.95, μ ≈ 0, our choice; `jaxmotion/training/meta.py`).
The paper's learned w (Fig. 7): the lower body follows the meta policy, the upper body does not.

Train the meta policy first (`make train EXP=goal/location_walk`); `meta` below takes its
newest run, or name one: `make train EXP=incremental/aim+walk ARGS="meta=runs/goal/location_walk/<stamp>"`.
`python -m jaxmotion.eval <run>` prints the mean w per body group and writes `meta_weights.png`.
Results: docs/results.md, "Incremental learning".
"""

from _common import incremental


def config():
    return incremental("goal/aim+walk", meta="runs/goal/location_walk")
