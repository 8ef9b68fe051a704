r"""A rigid body on a skate's blade (a knife edge) on a plane: Maggi's (82) or Appell's equations (§60) on SE(3).

The blade stands in a plane of the body, the blade's plane, with unit normal $k$ (body
frame). Its contact point cannot move across the blade, only along it: along
$t = k\times n/|k\times n|$, the line where the blade's plane meets the plane of the
ice ($n$ its normal seen from the body). In parametric form (77) the characteristics are
the angular velocity and the contact point's speed along the blade, $e = (\omega, \sigma)$,
and $\xi = (\omega,\ c\times\omega + \sigma t)$ (`AbstractPlaneContactMode` with the one
sliding direction $t$). The sideways row is not integrable: the Chaplygin sleigh (seed
001's first example) is a body skating upright.
"""

import jax.numpy as jnp
from jaxtyping import Array, Float

from .._nonholonomic._contact import AbstractContactSurface, unit_axis
from .._nonholonomic._equations import AbstractNonholonomicEquations, MaggiEquations
from ._plane_contact import AbstractPlaneContactMode, check_contact

__all__ = ["SkatingMode"]


class SkatingMode(AbstractPlaneContactMode):
    r"""A rigid body on a skate's blade (a knife edge) that may slide along the blade but
    not across it, on a fixed plane (seed 001, (76), (77), (82)).

    The integration state is $y = (g, e)$, $e = (\omega, \sigma)$: the pose on SE(3), the
    body angular velocity and the contact point's speed along the blade, $t = k\times
    n/|k\times n|$ with $k$ the normal of the blade's plane and $n$ the plane's normal, both
    in the body frame. The body twist is $\xi = (\omega,\ c\times\omega + \sigma t)$. The
    blade's reaction is ideal and does no work, so the energy of a scene with conservative
    effects is conserved.

    The blade is the contact `surface`: `PointContact(c)` for a straight blade touching at
    one point (a sleigh's runner), `DiscContact(r, axis=k)` for a rockered skate's blade
    (an arc of radius $r$). Where the blade lies flat on the plane ($k = \pm n$) its
    direction along the plane is not defined: $t$ is taken as zero there (finite, with
    finite derivatives), the characteristic $\sigma$ drives nothing and the equations are
    singular, so a solve that reaches it fails rather than goes on.

    ```python
    sleigh = bd.RigidBody(mass, jnp.zeros(3), inertia)
    blade = bd.PointContact((-0.3, 0.0, 0.0))  # 0.3 behind the centre of mass
    scene = bd.Scene(sleigh, mode=bd.SkatingMode(blade, blade_axis=(0.0, 1.0, 0.0)))
    state = scene.mode.state(jnp.eye(4), omega=(0.0, 0.0, 2.0), sliding=(0.0,))
    ```

    **Arguments:**

    - `surface`: the blade's `AbstractContactSurface` (`PointContact`, `DiscContact`).
    - `blade_axis`: $k$, the normal of the blade's plane in the body frame (normalized);
      default $(0, 1, 0)$: a blade along the body's $x$ axis.
    - `normal`: the plane's upward normal in the world frame; default $(0, 0, 1)$.
    - `offset`: the plane is $\{x : n\cdot x = \text{offset}\}$; default 0.
    - `equations`: `MaggiEquations()` (default) or `AppellEquations()`, which give the same
      motion by two assemblies (`maggi_body_rates`, `appell_body_rates`).
    """

    surface: AbstractContactSurface
    blade_axis: Float[Array, "3"]
    normal: Float[Array, "3"]
    offset: Float[Array, ""]
    equations: AbstractNonholonomicEquations

    def __init__(
        self,
        surface,
        *,
        blade_axis=(0.0, 1.0, 0.0),
        normal=(0.0, 0.0, 1.0),
        offset=0.0,
        equations=None,
    ):
        self.surface = surface
        self.blade_axis = unit_axis("SkatingMode", blade_axis, "blade_axis")
        self.normal = unit_axis("SkatingMode", normal, "normal")
        self.offset = jnp.asarray(offset, dtype=float)
        self.equations = MaggiEquations() if equations is None else equations

    def __check_init__(self):
        check_contact("SkatingMode", self.surface, self.offset, self.equations)

    def sliding_directions(self, n):
        r"""The blade's direction on the plane, $t = k\times n/|k\times n|$, as a `(3, 1)`
        matrix; zero where the blade lies flat (double `where`)."""
        along = jnp.cross(self.blade_axis, n)
        squared = jnp.dot(along, along)
        flat = squared < jnp.finfo(n.dtype).eps ** 2
        safe = jnp.where(flat, jnp.ones_like(squared), squared)
        t = jnp.where(flat, jnp.zeros_like(along), along / jnp.sqrt(safe))
        return t[:, None]
