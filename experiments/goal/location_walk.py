"""Target location with full-body walk imitation (the paper's meta policy for incremental
learning, P §6.5; the authors' `config/locomotion_walk.py`): one full-body discriminator on the
LAFAN1 walk clips and the location reward, ω 0.5 / 0.5. Radius, speeds and timers as notes §1.
CPU-sized networks (`_common.goal`); the paper trains these for 1-4 x 10^8 samples. It is the
meta policy of `incremental/aim+walk`. Results: docs/results.md, "Going to a location".
"""

from _common import WALK, LOCATION_WALK, GroupConfig, TaskConfig, goal


def config():
    return goal(TaskConfig(name="location", location=LOCATION_WALK), (GroupConfig(name="full", motions=WALK),), WALK)
