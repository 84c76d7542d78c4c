"""Target location with full-body run imitation (the paper's meta policy for incremental
learning, P §6.5; the authors' `config/locomotion_run.py`): one full-body discriminator on the
LAFAN1 run clips and the location reward, ω 0.5 / 0.5. Radius, speeds and timers as notes §1.
CPU-sized networks (`_common.goal`). Results: docs/results.md, "Running to a location".
"""

from _common import RUN, LOCATION_RUN, GroupConfig, TaskConfig, goal


def config():
    return goal(TaskConfig(name="location", location=LOCATION_RUN), (GroupConfig(name="full", motions=RUN),), RUN)
