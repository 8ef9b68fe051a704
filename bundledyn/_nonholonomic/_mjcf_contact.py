r"""The rolling surface of an imported MJCF model's geom, in its body's frame."""

import numpy as np

from .._systems._mujoco_import import compiled_mjcf
from ._contact import AbstractContactSurface, EllipsoidContact, SphereContact

__all__ = ["contact_surface_from_mjcf"]

# mjtGeom codes (MuJoCo's `mjGEOM_*`), fixed by its file format.
_SPHERE, _CAPSULE, _ELLIPSOID, _CYLINDER = 2, 3, 4, 5
_ALIGNED = 1e-12


def contact_surface_from_mjcf(source, geom: str) -> AbstractContactSurface:
    r"""The surface of the MJCF geom `geom` as a rolling contact of its body (`RollingMode`).

    A `sphere` gives `SphereContact` and an `ellipsoid` `EllipsoidContact`, placed at the
    geom's position in its body's frame: the frame in which bundledyn places an imported
    body (`Scene.from_mjcf`). A cylinder or a capsule touches a plane along a line when it
    stands on its side, not at a point, so it is refused; build a thin wheel as
    `DiscContact(radius, axis, centre)` instead.

    **Arguments:**

    - `source`: a path to an MJCF file, an MJCF XML string, or a `mujoco.MjModel`.
    - `geom`: the geom's name.

    **Returns:**

    The `AbstractContactSurface`.
    """
    model = compiled_mjcf(source)
    names = [model.geom(i).name for i in range(model.ngeom)]
    if geom not in names:
        raise ValueError(f"the model has no geom named {geom!r}; its geoms: {names}.")
    g = names.index(geom)
    kind = int(model.geom_type[g])
    centre = np.array(model.geom_pos[g], dtype=float)
    size = np.array(model.geom_size[g], dtype=float)
    if kind == _SPHERE:
        return SphereContact(size[0], centre)
    if kind == _ELLIPSOID:
        if np.max(np.abs(np.abs(model.geom_quat[g]) - np.array([1.0, 0, 0, 0]))) > _ALIGNED:
            raise ValueError(
                f"geom {geom!r}: an ellipsoid rolls here with its semi-axes along its body's "
                "axes; rotate the body, not the geom (its quat must be the identity)."
            )
        return EllipsoidContact(size, centre)
    if kind in (_CAPSULE, _CYLINDER):
        raise ValueError(
            f"geom {geom!r} is a {'capsule' if kind == _CAPSULE else 'cylinder'}, which touches "
            "a plane along a line on its side: give a sphere or ellipsoid geom, or build "
            "`DiscContact(radius, axis, centre)` for a thin wheel."
        )
    raise ValueError(f"geom {geom!r} is not a sphere or an ellipsoid; it cannot roll here.")
