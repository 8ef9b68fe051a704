"""The frames a trajectory's quantities are in, named for titles and printed summaries.

A trajectory's poses and velocities are in its scene's frame; its energy and spatial
momentum are in the Galilean frame whatever the scene's frame (`Trajectory.energy`,
`Trajectory.spatial_momentum`). Needs no matplotlib: the command line prints these names.
"""

from .._frames import Boosted, FreeFalling
from .._scene import Scene

GALILEAN = "the Galilean frame"


def frame_name(scene: Scene) -> str:
    """The frame a scene's poses are in, in words (`"the falling frame"`).

    **Arguments:**

    - `scene`: a `Scene`.

    **Returns:**

    `"the Galilean frame"`, `"the falling frame"`, `"the boosted frame"` or `"the moving
    frame"` (any other `AbstractFrame`).
    """
    if scene.frame is None:
        return GALILEAN
    if isinstance(scene.frame, FreeFalling):
        return "the falling frame"
    if isinstance(scene.frame, Boosted):
        return "the boosted frame"
    return "the moving frame"
