"""Track every shared clip on the 15-body humanoid (notes phc.md §7): the 95 distinct clips, the
sword-and-shield ones without their props, minus the 15 of the development split
`_common.TRACK_DEV`: 80 clips, 598 s; the rotation goal (15 x 24 goal features). Evaluate on the
held-out clips with `python -m jaxmotion.eval <run> --clips <dev clip paths>`.
Results: docs/tracker.md, "All clips on a GPU".
"""

from _common import TRACK_TRAIN, track


def config():
    return track(TRACK_TRAIN)
