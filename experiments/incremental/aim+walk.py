"""Aiming + target location while walking, learned incrementally (paper §5, Eq. 10, §6.5): the
same scene, objectives and ω as `goal/aim+walk`, with the frozen `goal/location_walk` policy as
the meta policy. The new policy outputs μ, σ and a weight w per DoF of the meta policy's sampled
action; it starts as the meta policy (w = 0.95, μ ≈ 0; `jaxmotion/meta.py`). The paper's
learned w (Fig. 7): the lower body follows the meta policy, the upper body does not.

Train the meta policy first (`make train EXP=goal/location_walk`); `meta` below takes its
newest run, or name one: `make train EXP=incremental/aim+walk ARGS="meta=runs/goal/location_walk/<stamp>"`.
`python -m jaxmotion.eval <run>` prints the mean w per body group and writes `meta_weights.png`.

Measured on the 2-core CPU (2026-12-04, seed 0, meta = goal/location_walk at 10.2M samples;
README "Incremental vs scratch"): at 7.0M samples, 16 episodes, upper / lower DTW 0.152 / 0.091 m,
aim error 67 deg, 1 fall in 16, 8 of 56 goals reached (scratch: 0.108 / 0.115 m, 52 deg, 2 falls,
7 of 52). Full-length episodes from 0.94M samples (scratch 3.24M). w stayed at 0.94 / 0.95
(upper / lower): at the actor learning rate 5e-6 the sigmoid head hardly moves, so the upper body
must cancel the meta's arm swing through mu; the video shows a walk with the forearms held up
near the chest, pointing along the aim arrow only at times.
"""

from _common import incremental


def config():
    return incremental("goal/aim+walk", meta="runs/goal/location_walk")
