"""Target location with full-body run imitation (the paper's meta policy for incremental
learning, P §6.5; the authors' `config/locomotion_run.py`): one full-body discriminator on the
LAFAN1 run clips and the location reward, ω 0.5 / 0.5. Radius, speeds and timers as notes §1.
CPU-sized networks (`_common.goal`).

Measured on the 2-core CPU (2026-12-05; `make train EXP=goal/location_run ARGS="iterations=2000"`,
8.2M samples, 1 h 55 min beside three other jobs; `python -m jaxmotion.eval <run> --episodes 16`):
not yet learned. Falls in 10 of 16 episodes (7.2 s on average), run DTW 0.250 m, 2 of 38 goals
reached (5%), mean distance 4.19 m, reward 0.118. Running needs more samples than walking
(`location_walk` reached 6% of its goals at 10.2M, 53% at 20.5M)."""

from _common import RUN, LOCATION_RUN, GroupConfig, TaskConfig, goal


def config():
    return goal(TaskConfig(name="location", location=LOCATION_RUN), (GroupConfig(name="full", motions=RUN),), RUN)
