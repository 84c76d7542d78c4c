"""Upper body: punch (gym/punch, 1.3 s); lower body: the four LAFAN1 walk clips.

The paper's Table 1 row 6 pairs punch with a 1.1 s walk (0.11 m / 0.10 m). Without a goal task
the character may walk in any direction.
"""

from _common import GYM, WALK, composite


def config():
    return composite((GYM + "punch.json",), WALK)
