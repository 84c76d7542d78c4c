"""Track every usable shared clip of the 15-body humanoid (notes phc.md §7; what remains after the
development split of `_common.TRACK_DEV`: 35 clips), with the rotation goal (15 x 24 goal features).
Evaluate on the held-out clips with `python -m jaxmotion.eval <run> --clips <dev clip paths>`."""

from _common import TRACK_TRAIN, track


def config():
    return track(TRACK_TRAIN)
