"""Aiming + target location while running, learned incrementally (paper §5, Eq. 10, §6.5): the
same scene, objectives and ω as `goal/aim+run`, with the frozen `goal/location_run` policy as
the meta policy. The new policy outputs μ, σ and a weight w per DoF of the meta policy's sampled
action; it starts as the meta policy (w = 0.95, μ ≈ 0; `jaxmotion/training/meta.py`). The paper's
learned w (Fig. 7): the lower body follows the meta policy, the upper body does not.

Train the meta policy first (`make train EXP=goal/location_run`); `meta` below takes its
newest run, or name one: `make train EXP=incremental/aim+run ARGS="meta=runs/goal/location_run/<stamp>"`.
`python -m jaxmotion.eval <run>` prints the mean w per body group and writes `meta_weights.png`.
"""

from _common import incremental


def config():
    return incremental("goal/aim+run", meta="runs/goal/location_run")
