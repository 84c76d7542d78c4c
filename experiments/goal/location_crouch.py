"""Target location with full-body crouch imitation (the paper's meta policy for incremental
learning, P §6.5; the authors' `config/locomotion_crouch.py`): one full-body discriminator on the
LAFAN1 crouch clips and the location reward, ω 0.5 / 0.5. Radius, speeds and timers as notes §1.
CPU-sized networks (`_common.goal`)."""

from _common import CROUCH, LOCATION_WALK, GroupConfig, TaskConfig, goal


def config():
    return goal(
        TaskConfig(name="location", location=LOCATION_WALK), (GroupConfig(name="full", motions=CROUCH),), CROUCH
    )
