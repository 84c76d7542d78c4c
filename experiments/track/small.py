"""A tracker of three short DeepMimic clips (walk, run, punch): the CPU-sized demonstration that
tracking is learned (success and g-MPJPE against the same seeds untrained, `eval --untrained`).
Results: docs/tracker.md, "Three clips on a CPU".
"""

from _common import track


def config():
    return track(
        ("deepmimic/humanoid3d_walk.txt", "deepmimic/humanoid3d_run.txt", "deepmimic/humanoid3d_punch.txt"),
        iterations=3000,
    )
