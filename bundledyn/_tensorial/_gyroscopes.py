r"""Chains of Lagrange gyroscopes in gravity (seed 000, §4): one model, formulations in tensor
coordinates, and the seed's closed form of the equations.

Body $k$ of the chain ($k = 1, \dots, n$) is axisymmetric, its axis $e_k$ pointing from its
pivot $P_k$ to its centre of mass $C_k$; $P_1$ is fixed at the origin, and $P_{k+1} = P_k +
l_ke_k$. With $c_k = |P_kC_k|$, the centres are $r_k = \sum_{j<k} l_je_j + c_ke_k$, and with
the body's moments of inertia $A_k$ (about a diameter through $C_k$) and $C_k^{\rm ax}$ (about
its axis),
$$T = \sum_k \tfrac12 m_k|\dot r_k|^2 + \tfrac12\,\omega_k\cdot J^c_k\,\omega_k,\quad
J^c_k = A_k(1 - e_ke_k^T) + C^{\rm ax}_k e_ke_k^T,\qquad \Pi = g\sum_k m_k\,r_k\cdot e_0,$$
$e_0$ the upward vertical. $T$ and $\Pi$ are written here once, in the bodies' axes and
angular velocities; the formulations only say how those follow from their coordinates.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .. import lie
from .._validation import concrete
from ._coordinates import TensorCoordinates, TensorVelocities
from ._system import TensorialSystem

__all__ = ["LagrangeGyroscopeChain"]

_AXIS = np.array([0.0, 0.0, 1.0])  # the body's symmetry axis in its own frame
_UP = np.array([0.0, 0.0, 1.0])


class LagrangeGyroscopeChain(eqx.Module):
    r"""A chain of $n$ Lagrange gyroscopes on spherical joints in gravity (seed 000, §4).

    **Arguments** (arrays of shape `(n,)`, leaves that `jax.grad` differentiates):

    - `masses`: $m_k$.
    - `lengths`: $l_k = |P_kP_{k+1}|$, pivot to the next pivot along the axis.
    - `centres`: $c_k = |P_kC_k|$, pivot to the centre of mass along the axis.
    - `transverse_inertias`: $A_k$, about a diameter through the centre of mass.
    - `axial_inertias`: $C^{\rm ax}_k$, about the symmetry axis.
    - `gravity`: $g$ (a scalar; the vertical $e_0$ is $+z$).

    `in_rotations()` is the system in the rotation tensors $Z_k$ (the seed's first
    formulation, (59)–(60)), `in_axes(a)` in the axes and spin angles $(e_k, \phi_k)$ (the
    second, with (42)); `closed_form_equations` evaluates (60). `in_universal_joints()` is
    the same bodies on universal joints instead, in $Z_1$ and the axes (the third, (61)).
    `to_mjcf` writes either chain for MuJoCo and `Multibody.from_mjcf`.
    """

    masses: Float[Array, " n"]
    lengths: Float[Array, " n"]
    centres: Float[Array, " n"]
    transverse_inertias: Float[Array, " n"]
    axial_inertias: Float[Array, " n"]
    gravity: Float[Array, ""]

    def __init__(self, masses, lengths, centres, transverse_inertias, axial_inertias, gravity=9.81):
        self.masses = jnp.asarray(masses, dtype=float)
        self.lengths = jnp.asarray(lengths, dtype=float)
        self.centres = jnp.asarray(centres, dtype=float)
        self.transverse_inertias = jnp.asarray(transverse_inertias, dtype=float)
        self.axial_inertias = jnp.asarray(axial_inertias, dtype=float)
        self.gravity = jnp.asarray(gravity, dtype=float)

    def __check_init__(self):
        fields = ("masses", "lengths", "centres", "transverse_inertias", "axial_inertias")
        shapes = {getattr(self, name).shape for name in fields}
        if len(shapes) != 1 or len(next(iter(shapes))) != 1 or not next(iter(shapes))[0]:
            raise ValueError(
                "`LagrangeGyroscopeChain`: masses, lengths, centres and the inertias must be "
                f"arrays of one shape (n,), n >= 1; got shapes {sorted(shapes)}."
            )
        for name in ("masses", "transverse_inertias", "axial_inertias"):
            values = concrete(getattr(self, name))
            if values is not None and not np.all(np.isfinite(values) & (values > 0)):
                raise ValueError(f"`LagrangeGyroscopeChain.{name}` must be finite and positive.")

    @property
    def size(self) -> int:
        """$n$, the number of bodies (static)."""
        return self.masses.shape[0]

    def energies(
        self,
        axes: Float[Array, "n 3"],
        axis_rates: Float[Array, "n 3"],
        angular_velocities: Float[Array, "n 3"],
    ) -> tuple[Float[Array, ""], Float[Array, ""]]:
        r"""$(T, \Pi)$ from the axes $e_k$, their rates $\dot e_k$ and the angular velocities $\omega_k$.

        **Arguments:**

        - `axes`, `axis_rates`, `angular_velocities`: shape `(n, 3)` each.

        **Returns:**

        The kinetic and the potential energy.
        """
        arms = self.lengths[:, None] * axes
        arm_rates = self.lengths[:, None] * axis_rates
        before = lambda x: jnp.cumsum(x, axis=0) - x  # Σ_{j<k}
        centres = before(arms) + self.centres[:, None] * axes
        velocities = before(arm_rates) + self.centres[:, None] * axis_rates
        along = jnp.sum(angular_velocities * axes, axis=-1)
        spin = self.axial_inertias * along**2
        tumble = self.transverse_inertias * (jnp.sum(angular_velocities**2, axis=-1) - along**2)
        kinetic = 0.5 * jnp.sum(self.masses * jnp.sum(velocities**2, axis=-1) + spin + tumble)
        potential = self.gravity * jnp.sum(self.masses * (centres @ _UP))
        return kinetic, potential

    def in_rotations(self) -> TensorialSystem:
        r"""The chain in the rotation tensors $Z_k$ of its bodies: $e_k = Z_ke_3$,
        $\omega_k = (\dot Z_kZ_k^T)^\vee$ (the seed's first formulation, (59)–(60)).

        **Returns:**

        A `TensorialSystem` with $n$ rotations and nothing else.
        """
        return TensorialSystem(_InRotations(self), Pi=_PotentialInRotations(self))

    def in_axes(self, reference) -> TensorialSystem:
        r"""The chain in its axes and spin angles $(e_k, \phi_k)$: $\omega_k = \dot\phi_ke_k + A_k\dot e_k$ (42)
        (the seed's second formulation).

        **Arguments:**

        - `reference`: $a$, the fixed vector of (41)–(42), shape `(3,)`; the formulation is
          singular where an axis passes through $\pm a$.

        **Returns:**

        A `TensorialSystem` with $n$ scalars $\phi_k$ and $n$ unit vectors $e_k$.
        """
        reference = jnp.asarray(reference, dtype=self.masses.dtype)
        return TensorialSystem(_InAxes(self, reference), Pi=_PotentialInAxes(self))

    def in_universal_joints(self) -> TensorialSystem:
        r"""The chain with universal joints: body 1 on its spherical pivot, every other body
        $k$ on a universal joint whose first axis $u_k = Z_{k-1}e_2$ is fixed in body $k-1$
        (the seed's third formulation, (61)–(62)).

        The coordinates are $Z_1$ and the axes $e^{(2)}, \dots, e^{(n)}$; body $k$'s basis
        is $e^{(k)}_1 = u_k\times e^{(k)}/|u_k\times e^{(k)}|$ (its second joint axis, fixed
        in body $k$), $e^{(k)}_2 = e^{(k)}\times e^{(k)}_1$, $e^{(k)}_3 = e^{(k)}$, and its
        absolute angular velocity (61) comes by differentiating those bases. Singular where
        an axis lines up with its joint's first axis.

        **Returns:**

        A `TensorialSystem` with one rotation and $n - 1$ unit vectors.
        """
        return TensorialSystem(_InUniversalJoints(self), Pi=_PotentialInUniversalJoints(self))

    def universal_joint_rotations(self, X: TensorCoordinates) -> Float[Array, "n 3 3"]:
        r"""The bodies' rotations at a configuration of `in_universal_joints()`: $Z_1$, then
        each body's basis $(e^{(k)}_1, e^{(k)}_2, e^{(k)})$ as columns.

        **Arguments:**

        - `X`: $Z_1$ and the axes $e^{(2)}, \dots, e^{(n)}$.

        **Returns:**

        The rotations, shape `(n, 3, 3)`.
        """
        return _bases_of_universal_joints(X.rotations[0], X.unit_vectors)

    def axes_state(
        self, X: TensorCoordinates, V: TensorVelocities, reference
    ) -> tuple[TensorCoordinates, TensorVelocities]:
        r"""A state of `in_rotations()` as the same state of `in_axes(reference)`.

        $e_k = Z_ke_3$ and $\phi_k$ from (41) (`lie.unit_vector_and_angle_from_rotation`);
        $\Omega_k = \omega_k - (\omega_k\cdot e_k)e_k$ (so $\dot e_k = \omega_k\times e_k$)
        and $\dot\phi_k = (\omega_k - A_k\dot e_k)\cdot e_k$ from (42).

        **Arguments:**

        - `X`, `V`: the rotations and their angular velocities.
        - `reference`: $a$, as for `in_axes`.

        **Returns:**

        `(X, V)` in the axes and spin angles.
        """
        reference = jnp.asarray(reference, dtype=X.rotations.dtype)
        axes, angles = lie.unit_vector_and_angle_from_rotation(X.rotations, reference)
        omega = V.rotations
        along = jnp.sum(omega * axes, axis=-1, keepdims=True)
        axis_omega = omega - along * axes
        tumbling = lie.angular_velocity_from_unit_vector_and_angle(
            axes, angles, jnp.cross(omega, axes), jnp.zeros_like(angles), reference
        )
        spin_rates = jnp.sum((omega - tumbling) * axes, axis=-1)
        empty = jnp.zeros((0, 3, 3), X.rotations.dtype)
        return (
            TensorCoordinates(angles, axes, empty),
            TensorVelocities(spin_rates, axis_omega, jnp.zeros((0, 3), X.rotations.dtype)),
        )

    def to_mjcf(self, joints: str = "ball") -> str:
        r"""The chain as an MJCF model: a massive base welded to the world (bundledyn's
        import keeps it as the floating root: hold it with `PrescribedBase.fixed()`) and
        the bodies at their pivots, each with its $z$ axis on the symmetry axis, its centre
        of mass at $c_k$ and its principal inertias $(A_k, A_k, C^{\rm ax}_k)$; gravity
        $-g e_z$. One model for MuJoCo, `Multibody.from_mjcf` and the tensor formulations.

        **Arguments:**

        - `joints`: `"ball"` (every body on a ball joint: `in_rotations`, `in_axes`) or
          `"universal"` (body 1 on a ball joint, the others on two hinges, about the
          parent's $y$ then the child's $x$: `in_universal_joints`, whose bases are then the
          bodies' frames).

        **Returns:**

        The XML text.
        """
        if joints not in ("ball", "universal"):
            raise ValueError(f'`to_mjcf(joints=...)` is "ball" or "universal", got {joints!r}.')
        universal = '<joint type="hinge" axis="0 1 0"/><joint type="hinge" axis="1 0 0"/>'
        values = {
            name: np.asarray(getattr(self, name), dtype=float).tolist()
            for name in ("masses", "lengths", "centres", "transverse_inertias", "axial_inertias")
        }
        bodies, offset = [], 0.0
        for k in range(self.size):
            m, c = values["masses"][k], values["centres"][k]
            A, C = values["transverse_inertias"][k], values["axial_inertias"][k]
            bodies.append(
                f'<body name="gyroscope{k + 1}" pos="0 0 {offset!r}">'
                + (universal if joints == "universal" and k else '<joint type="ball"/>')
                + f'<inertial pos="0 0 {c!r}" mass="{m!r}" diaginertia="{A!r} {A!r} {C!r}"/>'
            )
            offset = values["lengths"][k]
        nested = "".join(bodies) + "</body>" * self.size
        return (
            '<mujoco model="lagrange_gyroscope_chain">'
            f'<option gravity="0 0 {-float(self.gravity)!r}"/>'
            '<worldbody><body name="base">'
            '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>'
            f"{nested}</body></worldbody></mujoco>"
        )

    def pivot_inertias(self) -> tuple[Float[Array, " n"], Float[Array, " n"]]:
        r"""The augmented bodies' moments of inertia about their pivots: the transverse one
        $A_k + m_kc_k^2 + l_k^2\sum_{j>k}m_j$ and the axial one $C^{\rm ax}_k$ (the bodies
        outboard of $k$ concentrated at $P_{k+1}$, on the axis)."""
        outboard = jnp.cumsum(self.masses[::-1])[::-1] - self.masses
        transverse = self.transverse_inertias + self.masses * self.centres**2
        return transverse + outboard * self.lengths**2, self.axial_inertias

    def couplings(self) -> tuple[Float[Array, " n"], Float[Array, "n n"]]:
        r"""The seed's constants $Mb_k$ and $g_{kj}$ (§4), for the chain's path matrix
        ($T_{kj} = -1$ for $k \le j$).

        $Mb_k = m_kc_k + l_k\sum_{j>k}m_j$, the first moment of the augmented body $k$ about
        its pivot, and $g_{kj} = l_{\min(k,j)}\,Mb_{\max(k,j)}$ for $k \ne j$ (zero on the
        diagonal), so that the translational energy's cross terms are
        $\tfrac12\sum_{k\ne j}g_{kj}\,\dot e_k\cdot\dot e_j$ — the seed's $g_{kj}$ with its
        factor $M$ written in.

        **Returns:**

        `(moments, couplings)`, shapes `(n,)` and `(n, n)`.
        """
        outboard = jnp.cumsum(self.masses[::-1])[::-1] - self.masses
        moments = self.masses * self.centres + outboard * self.lengths
        k = jnp.arange(self.size)
        inner, outer = jnp.minimum(k[:, None], k[None, :]), jnp.maximum(k[:, None], k[None, :])
        couplings = jnp.where(inner == outer, 0.0, self.lengths[inner] * moments[outer])
        return moments, couplings

    def closed_form_equations(
        self, X: TensorCoordinates, V: TensorVelocities, A: TensorVelocities
    ) -> Float[Array, "n 3"]:
        r"""The left sides of the seed's (60) in the rotation tensors, at the rates $A$.

        $$\frac{d}{dt}(J_i\omega_i) + e_i\times\Big(\sum_{j\ne i} g_{ij}\,\ddot e_j
        + Mgb_i\,e_0\Big)$$
        with $J_i$ the augmented body's inertia about its pivot (`pivot_inertias`),
        $\ddot e_j = \dot\omega_j\times e_j + \omega_j\times(\omega_j\times e_j)$; zero on
        the motion. (The seed prints the gravity term inside the sum over $j$ in (60) and
        with the opposite sign in (59); it is written here as the theorem on the angular
        momentum of the augmented body $i$ about its pivot gives it, with $e_0$ upward.)

        **Arguments:**

        - `X`: the rotations (as `in_rotations()` takes them); `V`: their angular
          velocities; `A`: the angular accelerations.

        **Returns:**

        The $n$ equations, shape `(n, 3)`.
        """
        Z, omega, alpha = X.rotations, V.rotations, A.rotations
        axes = Z @ _AXIS
        axis_rates = jnp.cross(omega, axes)
        axis_accelerations = jnp.cross(alpha, axes) + jnp.cross(omega, axis_rates)
        transverse, axial = self.pivot_inertias()
        along = jnp.sum(omega * axes, axis=-1, keepdims=True)
        along_rate = jnp.sum(alpha * axes + omega * axis_rates, axis=-1, keepdims=True)
        # J ω = A ω + (C - A)(e·ω) e, differentiated along the motion.
        difference = (axial - transverse)[:, None]
        momentum_rate = transverse[:, None] * alpha + difference * (
            along_rate * axes + along * axis_rates
        )
        moments, couplings = self.couplings()
        pulls = couplings @ axis_accelerations + jnp.outer(self.gravity * moments, jnp.asarray(_UP))
        return momentum_rate + jnp.cross(axes, pulls)


class _InRotations(eqx.Module):
    chain: LagrangeGyroscopeChain

    def __call__(self, X, Xdot, t):
        Z, Zdot = X.rotations, Xdot.rotations
        spin = Zdot @ jnp.swapaxes(Z, -1, -2)
        omega = lie.so3_vee(0.5 * (spin - jnp.swapaxes(spin, -1, -2)))
        return self.chain.energies(Z @ _AXIS, Zdot @ _AXIS, omega)[0]


class _PotentialInRotations(eqx.Module):
    chain: LagrangeGyroscopeChain

    def __call__(self, X, t):
        axes = X.rotations @ _AXIS
        return self.chain.energies(axes, jnp.zeros_like(axes), jnp.zeros_like(axes))[1]


class _InAxes(eqx.Module):
    chain: LagrangeGyroscopeChain
    reference: Float[Array, "3"]

    def __call__(self, X, Xdot, t):
        axes, axis_rates = X.unit_vectors, Xdot.unit_vectors
        omega = lie.angular_velocity_from_unit_vector_and_angle(
            axes, X.scalars, axis_rates, Xdot.scalars, self.reference
        )
        return self.chain.energies(axes, axis_rates, omega)[0]


class _PotentialInAxes(eqx.Module):
    chain: LagrangeGyroscopeChain

    def __call__(self, X, t):
        axes = X.unit_vectors
        return self.chain.energies(axes, jnp.zeros_like(axes), jnp.zeros_like(axes))[1]


def _bases_of_universal_joints(first, axes):
    """The rotations of a chain with universal joints from $Z_1$ and the axes $e^{(2..n)}$."""
    rotations = [first]
    for axis in axes:
        joint_axis = rotations[-1][:, 1]  # u_k = Z_{k-1} e_2, fixed in the parent
        across = jnp.cross(joint_axis, axis)
        first_axis = across / jnp.linalg.norm(across)
        rotations.append(jnp.stack([first_axis, jnp.cross(axis, first_axis), axis], axis=-1))
    return jnp.stack(rotations)


class _InUniversalJoints(eqx.Module):
    chain: LagrangeGyroscopeChain

    def __call__(self, X, Xdot, t):
        Z, Zdot = jax.jvp(
            _bases_of_universal_joints,
            (X.rotations[0], X.unit_vectors),
            (Xdot.rotations[0], Xdot.unit_vectors),
        )
        spin = Zdot @ jnp.swapaxes(Z, -1, -2)
        omega = lie.so3_vee(0.5 * (spin - jnp.swapaxes(spin, -1, -2)))
        return self.chain.energies(Z @ _AXIS, Zdot @ _AXIS, omega)[0]


class _PotentialInUniversalJoints(eqx.Module):
    chain: LagrangeGyroscopeChain

    def __call__(self, X, t):
        axes = _bases_of_universal_joints(X.rotations[0], X.unit_vectors) @ _AXIS
        return self.chain.energies(axes, jnp.zeros_like(axes), jnp.zeros_like(axes))[1]
