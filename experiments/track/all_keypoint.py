"""`track/all` with the keypoint goal (positions and velocities only, 15 x 9 goal features; the
reward still uses rotations), for the rotation-vs-keypoint comparison of the PHC paper."""

from _common import TRACK_TRAIN, track


def config():
    return track(TRACK_TRAIN, goal="keypoint")
