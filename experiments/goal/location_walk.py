"""Target location with full-body walk imitation (the paper's meta policy for incremental
learning, P §6.5; the authors' `config/locomotion_walk.py`): one full-body discriminator on the
LAFAN1 walk clips and the location reward, ω 0.5 / 0.5. Radius, speeds and timers as notes §1.
CPU-sized networks (`_common.goal`).

Measured on the 2-core CPU (2026-12-04; `make train EXP=goal/location_walk ARGS="iterations=2500"`,
10.2M samples in 69 min beside other runs; `python -m jaxmotion.eval <run> --episodes 16`): it
walks (DTW 0.120 m, 100% of the walk frames within 0.1 m of a played one) and stays up in 11 of
16 episodes (13.9 s of 16.7 on average), but steers poorly: 3 of 47 goals reached (6%), mean
distance to the target 3.0 m, location reward 0.29. Untrained: falls after 0.72 s, reward 0.15.
The paper trains these for 1-4 x 10^8 samples. It is the meta policy of `incremental/aim+walk`.
Retrained 2026-12-04 on another host (1500 iterations, then resumed to 2500): the same 16-episode
figures at the precision above (13.9 s, DTW 0.120 m, 3 of 47, 3.03 m, reward 0.294).
Resumed to 5000 iterations (2026-12-05, `resume=<run> iterations=5000`, 20.5M samples): it steers,
25 of 47 goals reached (53%), mean distance 2.79 m, reward 0.465, 4/16 falls, 14.0 s, DTW 0.099 m."""

from _common import WALK, LOCATION_WALK, GroupConfig, TaskConfig, goal


def config():
    return goal(TaskConfig(name="location", location=LOCATION_WALK), (GroupConfig(name="full", motions=WALK),), WALK)
