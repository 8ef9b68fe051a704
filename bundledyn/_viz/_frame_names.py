"""The frames a trajectory's quantities are in, named for titles and printed summaries.

A trajectory's poses and velocities are in its scene's frame; its energy and spatial
momentum are in the Galilean frame whatever the scene's frame (`Trajectory.energy`,
`Trajectory.spatial_momentum`). Needs no matplotlib: the command line prints these names.
"""

from .._scene import Scene

GALILEAN = "the Galilean frame"


def frame_name(scene: Scene) -> str:
    """The frame a scene's poses are in, in words (`"the falling frame"`).

    **Arguments:**

    - `scene`: a `Scene`.

    **Returns:**

    `"the Galilean frame"` without a frame, else the frame's `name` (`"the falling
    frame"`, `"the boosted frame"`, `"the moving frame"` for any other `AbstractFrame`).
    """
    return GALILEAN if scene.frame is None else scene.frame.name
