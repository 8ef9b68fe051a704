r"""The Whipple bicycle: four rigid bodies, two wheels rolling without slipping (seed 001, §54–§58)."""

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .. import lie
from .._implicit import implicit_root
from .._validation import check_shape, concrete
from ._constraints import AbstractKinematicConstraints
from ._equations import AbstractNonholonomicEquations, MaggiEquations
from ._linearize import linearization
from ._pfaffian import PfaffianConstraints
from ._system import AbstractNonholonomicSystem
from ._term import NonholonomicTerm

# Newton's iterations for the pitch: quadratic convergence from the upright pitch reaches
# rounding in four to five at the roll and steer angles a bicycle meets; the rest is margin.
_NEWTON_STEPS = 12
_DOWN = np.array([0.0, 0.0, 1.0])  # the ground's downward normal: z points down, as in the paper
# In the state (q, e) = (x, y, psi, phi, theta_B, delta, theta_R, theta_F, phi', delta', theta_R'):
_ROLL_AND_STEER = np.array([3, 5, 8, 9])


def _about_x(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    zero, one = jnp.zeros_like(c), jnp.ones_like(c)
    return jnp.stack(
        [jnp.stack([one, zero, zero]), jnp.stack([zero, c, -s]), jnp.stack([zero, s, c])]
    )


def _about_y(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    zero, one = jnp.zeros_like(c), jnp.ones_like(c)
    return jnp.stack(
        [jnp.stack([c, zero, s]), jnp.stack([zero, one, zero]), jnp.stack([-s, zero, c])]
    )


def _about_z(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    zero, one = jnp.zeros_like(c), jnp.ones_like(c)
    return jnp.stack(
        [jnp.stack([c, -s, zero]), jnp.stack([s, c, zero]), jnp.stack([zero, zero, one])]
    )


def _wheel_contact(centre, axle, radius):
    r"""The point of a wheel (a disc of `radius` about `axle` through `centre`) lowest along
    the ground's downward normal $n$: $c + r\,(n - (n\cdot a)a)/|n - (n\cdot a)a|$."""
    down = jnp.asarray(_DOWN, centre.dtype)
    in_plane = down - (down @ axle) * axle
    return centre + radius * in_plane / jnp.linalg.norm(in_plane)


class Placement(NamedTuple):
    r"""Where the bicycle's parts are at a configuration $q$ (ground frame, $z$ down).

    `rotations` and `centres` hold the rear wheel, the rear frame, the front frame and the
    front wheel, in that order: rotation matrices `(4, 3, 3)` and centres of mass `(4, 3)`.
    `contacts` are the wheels' lowest points `(2, 3)`, rear first."""

    rotations: Float[Array, "4 3 3"]
    centres: Float[Array, "4 3"]
    contacts: Float[Array, "2 3"]


class WhippleBicycle(AbstractNonholonomicSystem):
    r"""The Whipple bicycle of Meijaard, Papadopoulos, Ruina & Schwab (2007), from its nonlinear model.

    Four rigid bodies: the rear wheel $R$, the rear frame $B$ with the rider, the front
    frame $H$ (fork and handlebar) and the front wheel $F$. $H$ turns about the steer axis,
    tilted back by $\lambda$ from the vertical; the wheels are knife-edge discs that roll
    without slipping on the level ground. Axes and parameters are the paper's (§2, Table 1):
    at the upright reference the rear contact is the origin, $x$ points forward, $z$ down,
    the wheelbase is $w$, the trail $c$ (the steer axis meets the ground $c$ ahead of the
    front contact), and the centres of mass and inertias of $B$ and $H$ are given in that
    reference frame.

    **Coordinates** $q = (x, y, \psi, \phi, \theta_B, \delta, \theta_R, \theta_F)$ (the
    paper's): the rear contact point, the yaw, roll, pitch and steer angles and the wheels'
    rotation angles. The rear frame's orientation is $R_z(\psi)R_x(\phi)R_y(\theta_B)$ and
    the rear wheel touches the ground at $(x, y, 0)$ by construction. The front wheel
    touches it where the holonomic constraint $f(\theta_B; \phi, \delta) = 0$ holds
    (`front_contact_height`); `pitch` solves it by Newton's method, with the implicit
    function's derivatives, and `on_the_ground` puts a configuration on it.

    **Constraints** (76): the material points of the wheels at their contacts do not move,
    $v_c + \omega\times(p - c) = 0$: the horizontal components of both wheels' and the
    vertical one of the front wheel's, which is $\dot f$, the holonomic constraint carried
    in its differentiated form (the rear wheel's vanishes identically). Five Pfaffian rows,
    solved for $(\dot x, \dot y, \dot\psi, \dot\theta_B, \dot\theta_F)$, the
    characteristics being $e = (\dot\phi, \dot\delta, \dot\theta_R)$
    (`PfaffianConstraints`, `independent=(3, 5, 6)`). $f$ is then a first integral, kept by
    the integrator to its tolerance: `front_contact_height` reports it.

    **Energy.** $T = \sum_i \tfrac12 m_i|\dot r_i|^2 + \tfrac12\omega_i^T R_i J_i R_i^T
    \omega_i$ over the four bodies, with velocities by autodiff of their placements;
    $\Pi = -g\sum_i m_i z_i$.

    Upright straight running at any speed $v$ is a steady motion (`steady_motion`); the
    eigenvalues of the linearized equations about it (`eigenvalues`) are the benchmark's
    Table 2, and `stability_boundary` finds the weave and capsize speeds.

    **Arguments** (all numbers, so they are leaves that `jax.grad` differentiates):

    - `wheelbase`, `trail`, `steer_axis_tilt`: $w$, $c$, $\lambda$.
    - `gravity`: $g$.
    - `rear_wheel_radius`, `rear_wheel_mass`, `rear_wheel_inertia`: $r_R$, $m_R$ and
      $(I_{Rxx}, I_{Ryy})$ (about a diameter and about the axle).
    - `rear_frame_centre`, `rear_frame_mass`, `rear_frame_inertia`: $(x_B, z_B)$, $m_B$ and
      the $3\times3$ inertia about the centre of mass.
    - `front_frame_centre`, `front_frame_mass`, `front_frame_inertia`: likewise for $H$.
    - `front_wheel_radius`, `front_wheel_mass`, `front_wheel_inertia`: as for the rear wheel.

    `WhippleBicycle.benchmark()` has the paper's values.
    """

    wheelbase: Float[Array, ""]
    trail: Float[Array, ""]
    steer_axis_tilt: Float[Array, ""]
    gravity: Float[Array, ""]
    rear_wheel_radius: Float[Array, ""]
    rear_wheel_mass: Float[Array, ""]
    rear_wheel_inertia: Float[Array, "2"]
    rear_frame_centre: Float[Array, "2"]
    rear_frame_mass: Float[Array, ""]
    rear_frame_inertia: Float[Array, "3 3"]
    front_frame_centre: Float[Array, "2"]
    front_frame_mass: Float[Array, ""]
    front_frame_inertia: Float[Array, "3 3"]
    front_wheel_radius: Float[Array, ""]
    front_wheel_mass: Float[Array, ""]
    front_wheel_inertia: Float[Array, "2"]

    def __init__(
        self,
        *,
        wheelbase,
        trail,
        steer_axis_tilt,
        gravity,
        rear_wheel_radius,
        rear_wheel_mass,
        rear_wheel_inertia,
        rear_frame_centre,
        rear_frame_mass,
        rear_frame_inertia,
        front_frame_centre,
        front_frame_mass,
        front_frame_inertia,
        front_wheel_radius,
        front_wheel_mass,
        front_wheel_inertia,
    ):
        as_array = lambda x: jnp.asarray(x, dtype=float)
        self.wheelbase = as_array(wheelbase)
        self.trail = as_array(trail)
        self.steer_axis_tilt = as_array(steer_axis_tilt)
        self.gravity = as_array(gravity)
        self.rear_wheel_radius = as_array(rear_wheel_radius)
        self.rear_wheel_mass = as_array(rear_wheel_mass)
        self.rear_wheel_inertia = as_array(rear_wheel_inertia)
        self.rear_frame_centre = as_array(rear_frame_centre)
        self.rear_frame_mass = as_array(rear_frame_mass)
        self.rear_frame_inertia = as_array(rear_frame_inertia)
        self.front_frame_centre = as_array(front_frame_centre)
        self.front_frame_mass = as_array(front_frame_mass)
        self.front_frame_inertia = as_array(front_frame_inertia)
        self.front_wheel_radius = as_array(front_wheel_radius)
        self.front_wheel_mass = as_array(front_wheel_mass)
        self.front_wheel_inertia = as_array(front_wheel_inertia)

    def __check_init__(self):
        shapes = {
            "rear_wheel_inertia": (2,),
            "front_wheel_inertia": (2,),
            "rear_frame_centre": (2,),
            "front_frame_centre": (2,),
            "rear_frame_inertia": (3, 3),
            "front_frame_inertia": (3, 3),
        }
        for name in type(self).__dataclass_fields__:
            check_shape(f"WhippleBicycle.{name}", getattr(self, name), shapes.get(name, ()))
        positive = ("wheelbase", "gravity", "rear_wheel_radius", "front_wheel_radius")
        positive += ("rear_wheel_mass", "rear_frame_mass", "front_frame_mass", "front_wheel_mass")
        for name in positive:
            v = concrete(getattr(self, name))
            if v is not None and not (np.isfinite(v) and v > 0):
                raise ValueError(f"`WhippleBicycle.{name}` must be finite and positive, got {v}.")
        tilt = concrete(self.steer_axis_tilt)
        if tilt is not None and not abs(tilt) < np.pi / 2:
            raise ValueError(
                "`WhippleBicycle.steer_axis_tilt` must be less than pi/2 in magnitude (a steer "
                f"axis that meets the ground), got {tilt}."
            )

    @classmethod
    def benchmark(cls) -> "WhippleBicycle":
        """The benchmark bicycle of Meijaard et al. (2007), Table 1.

        **Returns:**

        A `WhippleBicycle` with the paper's parameters (SI units).
        """
        return cls(
            wheelbase=1.02,
            trail=0.08,
            steer_axis_tilt=np.pi / 10,
            gravity=9.81,
            rear_wheel_radius=0.3,
            rear_wheel_mass=2.0,
            rear_wheel_inertia=(0.0603, 0.12),
            rear_frame_centre=(0.3, -0.9),
            rear_frame_mass=85.0,
            rear_frame_inertia=[[9.2, 0.0, 2.4], [0.0, 11.0, 0.0], [2.4, 0.0, 2.8]],
            front_frame_centre=(0.9, -0.7),
            front_frame_mass=4.0,
            front_frame_inertia=[
                [0.05892, 0.0, -0.00756],
                [0.0, 0.06, 0.0],
                [-0.00756, 0.0, 0.00708],
            ],
            front_wheel_radius=0.35,
            front_wheel_mass=3.0,
            front_wheel_inertia=(0.1405, 0.28),
        )

    # --- the geometry of the front assembly, in the rear frame at the rear wheel's centre ---

    def _steer_axis(self):
        r"""The steer axis: its (downward) direction $s$ and its point on the ground at the
        upright reference, relative to the rear wheel's centre in the rear frame."""
        tilt = self.steer_axis_tilt
        direction = jnp.stack([jnp.sin(tilt), jnp.zeros_like(tilt), jnp.cos(tilt)])
        zero = jnp.zeros_like(tilt)
        point = jnp.stack([self.wheelbase + self.trail, zero, self.rear_wheel_radius])
        return direction, point

    def _in_rear_frame(self, x, z):
        """A point of the upright reference, given from the rear contact, relative to the rear
        wheel's centre."""
        return jnp.stack([x, jnp.zeros_like(x), z + self.rear_wheel_radius])

    def _front_assembly(self, steer):
        r"""The front frame's rotation $\exp(\delta\hat s)$ relative to the rear frame, and the
        front wheel's centre and the front frame's centre of mass, relative to the rear
        wheel's centre in the rear frame, steered by $\delta$."""
        direction, point = self._steer_axis()
        turn = lie.so3_exp(steer * direction)
        wheel = self._in_rear_frame(self.wheelbase, -self.front_wheel_radius)
        centre = self._in_rear_frame(*self.front_frame_centre)
        return turn, point + turn @ (wheel - point), point + turn @ (centre - point)

    def front_contact_height(self, pitch, roll, steer) -> Float[Array, ""]:
        r"""How far below the ground the front wheel's lowest point is: $f(\theta_B; \phi, \delta)$.

        The holonomic constraint of the front wheel touching the ground is $f = 0$.

        **Arguments:**

        - `pitch`, `roll`, `steer`: $\theta_B$, $\phi$, $\delta$.

        **Returns:**

        The $z$ coordinate (down) of the front wheel's lowest point, the rear wheel touching
        the ground.
        """
        zero = jnp.zeros_like(roll)
        q = jnp.stack([zero, zero, zero, roll, pitch, steer, zero, zero])
        return self.placement(q).contacts[1, 2]

    def pitch(self, roll, steer) -> Float[Array, ""]:
        r"""The rear frame's pitch $\theta_B(\phi, \delta)$ at which both wheels touch the ground.

        Newton's method on the holonomic constraint $f(\theta_B; \phi, \delta) = 0$
        (`front_contact_height`) from the upright pitch 0; its derivatives, of every order
        and with respect to the bicycle's parameters too, are those of the implicit
        function, $\partial\theta_B = -f_\theta^{-1}\,\partial f$. A configuration where
        Newton's method does not reach the constraint (the front wheel cannot touch the
        ground) raises (`equinox.error_if`).

        **Arguments:**

        - `roll`, `steer`: $\phi$ and $\delta$.

        **Returns:**

        $\theta_B$.
        """
        return _pitch(self, roll, steer)

    def on_the_ground(self, q: Float[Array, " 8"]) -> Float[Array, " 8"]:
        r"""$q$ with its pitch set by `pitch`, so that both wheels touch the ground.

        **Arguments:**

        - `q`: $(x, y, \psi, \phi, \theta_B, \delta, \theta_R, \theta_F)$; its $\theta_B$ is
          replaced.

        **Returns:**

        The configuration on the holonomic constraint.
        """
        return q.at[4].set(self.pitch(q[3], q[5]))

    def placement(self, q: Float[Array, " 8"]) -> Placement:
        r"""The four bodies' rotations and centres of mass and the wheels' contacts at $q$.

        **Arguments:**

        - `q`: $(x, y, \psi, \phi, \theta_B, \delta, \theta_R, \theta_F)$.

        **Returns:**

        A `Placement`.
        """
        x, y, yaw, roll, pitch, steer, rear_angle, front_angle = q
        heading = _about_z(yaw) @ _about_x(roll)
        frame = heading @ _about_y(pitch)
        contact = jnp.stack([x, y, jnp.zeros_like(x)])
        rear_centre = contact + heading @ jnp.stack([0.0, 0.0, -self.rear_wheel_radius])
        turn, wheel, front_centre = self._front_assembly(steer)
        steered = frame @ turn
        front_wheel = rear_centre + frame @ wheel
        rotations = jnp.stack(
            [
                heading @ _about_y(rear_angle),
                frame,
                steered,
                steered @ _about_y(front_angle),
            ]
        )
        centres = jnp.stack(
            [
                rear_centre,
                rear_centre + frame @ self._in_rear_frame(*self.rear_frame_centre),
                rear_centre + frame @ front_centre,
                front_wheel,
            ]
        )
        contacts = jnp.stack(
            [
                contact,
                _wheel_contact(front_wheel, steered[:, 1], self.front_wheel_radius),
            ]
        )
        return Placement(rotations, centres, contacts)

    def _masses_and_inertias(self):
        def wheel(inertia):
            return jnp.diag(jnp.stack([inertia[0], inertia[1], inertia[0]]))

        masses = jnp.stack(
            [
                self.rear_wheel_mass,
                self.rear_frame_mass,
                self.front_frame_mass,
                self.front_wheel_mass,
            ]
        )
        inertias = jnp.stack(
            [
                wheel(self.rear_wheel_inertia),
                self.rear_frame_inertia,
                self.front_frame_inertia,
                wheel(self.front_wheel_inertia),
            ]
        )
        return masses, inertias

    def _velocities(self, q, qdot):
        r"""The placement at $q$, the centres' velocities and the bodies' angular velocities
        $\omega_i = (\dot R_i R_i^T)^\vee$ (ground frame)."""
        placed, moving = jax.jvp(self.placement, (q,), (qdot,))
        omega = jax.vmap(lambda R, dR: lie.vee(dR @ R.T))(placed.rotations, moving.rotations)
        return placed, moving, omega

    def kinetic_energy(self, q, qdot, t):
        placed, moving, omega = self._velocities(q, qdot)
        masses, inertias = self._masses_and_inertias()
        spin = jnp.einsum("bji,bj->bi", placed.rotations, omega)  # body-frame angular velocity
        rotational = jnp.einsum("bi,bij,bj->", spin, inertias, spin)
        return 0.5 * (jnp.sum(masses * jnp.sum(moving.centres**2, axis=-1)) + rotational)

    def potential_energy(self, q, t):
        masses, _ = self._masses_and_inertias()
        return -self.gravity * masses @ self.placement(q).centres[:, 2]

    def generalized_forces(self, q, qdot, t):
        return -jax.grad(self.potential_energy)(q, t)

    def contact_velocities(self, q, qdot) -> Float[Array, "2 3"]:
        r"""The velocities of the wheels' material points at their contacts, $v_c + \omega\times(p - c)$.

        Zero on the motions the constraints allow; the rear one's vertical component vanishes
        on every motion of $q$, the front one's is $\dot f$.

        **Arguments:**

        - `q`, `qdot`: coordinates and velocities, shape `(8,)`.

        **Returns:**

        The rear and front contacts' velocities, shape `(2, 3)`.
        """
        placed, moving, omega = self._velocities(q, qdot)
        wheels = slice(None, None, 3)  # bodies 0 and 3
        arms = placed.contacts - placed.centres[wheels]
        return moving.centres[wheels] + jnp.cross(omega[wheels], arms)

    @property
    def constraints(self) -> AbstractKinematicConstraints:  # pyright: ignore[reportIncompatibleVariableOverride]
        r"""Rolling without slipping, the front wheel on the ground: five Pfaffian rows solved
        for $(\dot x, \dot y, \dot\psi, \dot\theta_B, \dot\theta_F)$."""
        return PfaffianConstraints(_RollingWheels(self), independent=(3, 5, 6))

    def steady_motion(self, speed) -> tuple[Float[Array, " 8"], Float[Array, " 3"]]:
        r"""The state $(q, e)$ of upright straight running at forward speed $v$.

        **Arguments:**

        - `speed`: $v$; the rear wheel turns at $\dot\theta_R = -v/r_R$.

        **Returns:**

        `(q, e)` with $q = 0$ and $e = (0, 0, -v/r_R)$.
        """
        speed = jnp.asarray(speed, dtype=self.wheelbase.dtype)
        zero = jnp.zeros_like(speed)
        return jnp.zeros(8, speed.dtype), jnp.stack([zero, zero, -speed / self.rear_wheel_radius])

    def eigenvalues(
        self, speed, equations: AbstractNonholonomicEquations | None = None
    ) -> Float[Array, "4"]:
        r"""The eigenvalues of the equations linearized about upright straight running at speed $v$.

        The Jacobian of the field at `steady_motion(speed)` (`linearization`, by autodiff of
        the nonlinear model), reduced to the roll and steer angles and rates $(\phi, \delta,
        \dot\phi, \dot\delta)$. The others decouple at first order: position, yaw and the
        wheels' angles are cyclic, and the pitch and the forward speed are even under the
        reflection $y \to -y$ that makes roll and steer odd (Meijaard et al. 2007, §5).

        **Arguments:**

        - `speed`: $v$.
        - `equations`: Maggi's (the default) or Appell's.

        **Returns:**

        The four eigenvalues, complex, in `jnp.linalg.eigvals`'s order.
        """
        term = NonholonomicTerm(self, MaggiEquations() if equations is None else equations)
        jacobian = linearization(term, self.steady_motion(speed))
        return jnp.linalg.eigvals(jacobian[np.ix_(_ROLL_AND_STEER, _ROLL_AND_STEER)])

    def spectral_abscissa(self, speed) -> Float[Array, ""]:
        r"""The largest real part of `eigenvalues(speed)`: upright straight running is
        asymptotically stable at $v$ exactly where it is negative.

        **Arguments:**

        - `speed`: $v$.

        **Returns:**

        $\max_k \operatorname{Re}\lambda_k(v)$.
        """
        return jnp.max(jnp.real(self.eigenvalues(speed)))


class _RollingWheels(eqx.Module):
    """The Pfaffian rows (76) of the two rolling wheels: their contacts' velocities (the rear
    one's vertical component, zero by construction, left out), linear in $\\dot q$."""

    bicycle: WhippleBicycle

    def __call__(self, q, t):
        def velocity(qdot):
            rear, front = self.bicycle.contact_velocities(q, qdot)
            return jnp.concatenate([rear[:2], front])

        return jax.jacfwd(velocity)(jnp.zeros_like(q))


def _pitch(bicycle, roll, steer):
    return implicit_root((bicycle, roll, steer), residual=_front_height, solve=_pitch_by_newton)


def _front_height(inputs, pitch):
    bicycle, roll, steer = inputs
    return bicycle.front_contact_height(pitch, roll, steer)


def _pitch_by_newton(inputs):
    bicycle, roll, _ = inputs

    def newton(_, pitch):
        height, slope = jax.value_and_grad(_front_height, argnums=1)(inputs, pitch)
        return pitch - height / slope

    pitch = jax.lax.fori_loop(0, _NEWTON_STEPS, newton, jnp.zeros_like(roll))
    residual = jnp.abs(_front_height(inputs, pitch))
    return eqx.error_if(
        pitch,
        ~(residual <= 1e-12 * bicycle.front_wheel_radius),
        "WhippleBicycle.pitch: Newton's method did not bring the front wheel to the ground at "
        "this roll and steer (no pitch puts both wheels on the ground).",
    )
