"""A tracker of three short DeepMimic clips (walk, run, punch): the CPU-sized demonstration that
tracking is learned (success and g-MPJPE against the same seeds untrained, `eval --untrained`).

Measured on the 2-core CPU (2026-12-05, residual targets, seed 0; README "Motion tracking"): at
12.3M samples (3000 iterations, 91 min sharing the cores) walk and punch are tracked to the end
(2/3, g-MPJPE 106 mm on them), the run to frame 19 of 24; untrained, same seed, 0/3 (26, 12 and
19 frames). With the actor's lr at the authors' 2e-5 (the default here since), the same 2/3
(walk and punch, g-MPJPE 109 mm) at 4.1M samples (1000 iterations), 90 mm at 6.1M, 95 mm at
12.3M (3000 iterations, 52 min for the last 6.1M, mostly sharing the cores); the run is lost at frame 20 of 24 (its
root falls behind the reference's 3.6 m/s from the first step). The keypoint goal
(``env.task.track.goal=keypoint``) alike at 6.1M: 2/3, 92 mm. On the 15 development clips
(``TRACK_DEV``) none is followed to its end, trained or not."""

from _common import track


def config():
    return track(("deepmimic/humanoid3d_walk.txt", "deepmimic/humanoid3d_run.txt", "deepmimic/humanoid3d_punch.txt"),
                 iterations=3000)
