"""Aiming + target location while crouching, learned incrementally (paper §5, Eq. 10, §6.5): the
same scene, objectives and ω as `goal/aim+crouch`, with the frozen `goal/location_crouch` policy as
the meta policy. The new policy outputs μ, σ and a weight w per DoF of the meta policy's sampled
action; it starts as the meta policy (w = 0.95, μ ≈ 0; `jaxmotion/training/meta.py`). The paper's
learned w (Fig. 7): the lower body follows the meta policy, the upper body does not.

Train the meta policy first (`make train EXP=goal/location_crouch`); `meta` below takes its
newest run, or name one: `make train EXP=incremental/aim+crouch ARGS="meta=runs/goal/location_crouch/<stamp>"`.
`python -m jaxmotion.eval <run>` prints the mean w per body group and writes `meta_weights.png`.
"""

from _common import incremental


def config():
    return incremental("goal/aim+crouch", meta="runs/goal/location_crouch")
