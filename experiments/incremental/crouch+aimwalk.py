"""Crouch + aiming + target location, learned incrementally from the aim+walk policy (paper §6.5,
Fig. 8): the upper body imitates the aiming clips, the lower body the crouch clips; the frozen
meta policy is the aim+walk policy (4 objectives), which already aims. The paper's learned w:
the new policy crouches by itself (lower-body w low) and takes the aiming from the meta policy
(upper-body w high).

The meta run: the newest of `runs/incremental/aim+walk` (train that first), or name one with
`ARGS="meta=<run folder>"` (a `goal/aim+walk` run works as well).
"""

from _common import incremental


def config():
    return incremental("goal/aim+crouch", meta="runs/incremental/aim+walk")
