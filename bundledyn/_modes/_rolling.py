r"""A rigid body rolling without slipping on a plane: Maggi's (82) or Appell's equations (§60) on SE(3).

The rolling constraints in parametric form (77) give the body twist from the angular
velocity, $\xi = H\omega$, $H = (I;\ \tilde c)$ (`contact_twist`): the contact point does
not slide at all (`AbstractPlaneContactMode` with no sliding directions).
"""

import jax.numpy as jnp
from jaxtyping import Array, Float

from .._nonholonomic._contact import AbstractContactSurface, unit_axis
from .._nonholonomic._equations import AbstractNonholonomicEquations, MaggiEquations
from ._plane_contact import AbstractPlaneContactMode, check_contact

__all__ = ["RollingMode"]


class RollingMode(AbstractPlaneContactMode):
    r"""A rigid body whose surface rolls without slipping on a fixed plane (seed 001, (77), (82)).

    The integration state is $y = (g, \omega)$: the pose on SE(3) (stepped by the Lie-group
    solvers) and the body angular velocity, the kinematic characteristics; the body twist
    is $\xi = (\omega, c\times\omega)$. Gravity and any other effects act as on a free
    body; the plane's reaction is ideal and does no work, so the energy of a scene with
    conservative effects is conserved.

    ```python
    ball = bd.RigidBody(mass, jnp.zeros(3), inertia)
    scene = bd.Scene(ball, [bd.Gravity(9.81)], mode=bd.RollingMode(bd.SphereContact(0.1)))
    state = scene.mode.state(g0, omega0)  # on the plane, with the rolling twist
    ```

    **Arguments:**

    - `surface`: the body's `AbstractContactSurface` (`SphereContact`, `DiscContact`,
      `TorusContact`, `EllipsoidContact`).
    - `normal`: the plane's upward normal in the world frame; default $(0, 0, 1)$.
    - `offset`: the plane is $\{x : n\cdot x = \text{offset}\}$; default 0.
    - `equations`: `MaggiEquations()` (default) or `AppellEquations()`, which give the same
      motion by two assemblies (`maggi_body_rates`, `appell_body_rates`).
    """

    surface: AbstractContactSurface
    normal: Float[Array, "3"]
    offset: Float[Array, ""]
    equations: AbstractNonholonomicEquations

    def __init__(self, surface, *, normal=(0.0, 0.0, 1.0), offset=0.0, equations=None):
        self.surface = surface
        self.normal = unit_axis("RollingMode", normal, "normal")
        self.offset = jnp.asarray(offset, dtype=float)
        self.equations = MaggiEquations() if equations is None else equations

    def __check_init__(self):
        check_contact("RollingMode", self.surface, self.offset, self.equations)

    def sliding_directions(self, n):
        """None: the contact point is at rest, a `(3, 0)` matrix."""
        return jnp.zeros((3, 0), n.dtype)
