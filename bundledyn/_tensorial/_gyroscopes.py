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
from ._coordinates import (
    TensorCoordinates,
    TensorVelocities,
    accelerations_of,
    angular_velocity,
    rates_of,
)
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
        centres, velocities = self._centres(axes, axis_rates)
        along = jnp.sum(angular_velocities * axes, axis=-1)
        spin = self.axial_inertias * along**2
        tumble = self.transverse_inertias * (jnp.sum(angular_velocities**2, axis=-1) - along**2)
        kinetic = 0.5 * jnp.sum(self.masses * jnp.sum(velocities**2, axis=-1) + spin + tumble)
        potential = self.gravity * jnp.sum(self.masses * (centres @ _UP))
        return kinetic, potential

    def _centres(self, axes, axis_rates):
        """The centres of mass $r_k$ and their velocities."""
        before = lambda x: jnp.cumsum(x, axis=0) - x  # Σ_{j<k}
        centres = before(self.lengths[:, None] * axes) + self.centres[:, None] * axes
        rates = before(self.lengths[:, None] * axis_rates) + self.centres[:, None] * axis_rates
        return centres, rates

    def angular_momentum(
        self,
        axes: Float[Array, "n 3"],
        axis_rates: Float[Array, "n 3"],
        angular_velocities: Float[Array, "n 3"],
    ) -> Float[Array, "3"]:
        r"""The chain's angular momentum about the fixed pivot, $\sum_k m_kr_k\times\dot r_k +
        J^c_k\omega_k$; its vertical component is a first integral (gravity's moment about
        the pivot is horizontal), as is the energy.

        **Arguments:**

        - `axes`, `axis_rates`, `angular_velocities`: shape `(n, 3)` each.

        **Returns:**

        The angular momentum, shape `(3,)`.
        """
        centres, velocities = self._centres(axes, axis_rates)
        along = jnp.sum(angular_velocities * axes, axis=-1, keepdims=True)
        spins = (
            self.transverse_inertias[:, None] * angular_velocities
            + (self.axial_inertias - self.transverse_inertias)[:, None] * along * axes
        )
        orbits = self.masses[:, None] * jnp.cross(centres, velocities)
        return jnp.sum(orbits + spins, axis=0)

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
        $k$ on a universal joint whose first axis is $e_2$ of body $k-1$ (the seed's third
        formulation, (61)–(62)).

        The coordinates are $Z_1$ and, for $k \ge 2$, the axis $\varepsilon_k$ of body $k$ in
        the basis of body $k-1$ ($e^{(k)} = Z_{k-1}\varepsilon_k$): the seed's relative
        vectors, whose rates are its relative derivatives. Body $k$'s basis in its parent's
        is $(e_2\times\varepsilon_k/|e_2\times\varepsilon_k|,\ \varepsilon_k\times\cdot,\
        \varepsilon_k)$, its first vector the joint's second axis, fixed in body $k$; the
        absolute angular velocities (61) come by differentiating the bases. Singular where
        an axis lines up with its joint's first axis.

        **Returns:**

        A `TensorialSystem` with one rotation and $n - 1$ unit vectors.
        """
        return TensorialSystem(_InUniversalJoints(self), Pi=_PotentialInUniversalJoints(self))

    def mujoco_state(
        self, X: TensorCoordinates, V: TensorVelocities
    ) -> tuple[np.ndarray, np.ndarray]:
        r"""MuJoCo's `qpos`, `qvel` of `to_mjcf("ball")` at a state of `in_rotations()`.

        Each ball joint's quaternion ($w$ first) is of $Z_{k-1}^TZ_k$ and its velocity is
        $Z_k^T(\omega_k - \omega_{k-1})$, the body's angular velocity relative to its parent
        in its own axes ($Z_0 = 1$, $\omega_0 = 0$).

        **Arguments:**

        - `X`, `V`: the rotations and their angular velocities.

        **Returns:**

        `(qpos, qvel)`, NumPy arrays of shapes `(4n,)` and `(3n,)`.
        """
        Z, omega = X.rotations, V.rotations
        parents = jnp.concatenate([jnp.eye(3, dtype=Z.dtype)[None], Z[:-1]])
        parent_omega = jnp.concatenate([jnp.zeros((1, 3), Z.dtype), omega[:-1]])
        relative = jnp.einsum("kji,kjl->kil", parents, Z)
        quaternions = jax.vmap(lie.quaternion_from_rotation)(relative)
        rates = jnp.einsum("kji,kj->ki", Z, omega - parent_omega)
        return np.asarray(quaternions).ravel(), np.asarray(rates).ravel()

    def universal_joint_rotations(self, X: TensorCoordinates) -> Float[Array, "n 3 3"]:
        r"""The bodies' rotations at a configuration of `in_universal_joints()`: $Z_1$, then
        $Z_k = Z_{k-1}R(\varepsilon_k)$, $R(\varepsilon_k)$ body $k$'s basis in its parent's.

        **Arguments:**

        - `X`: $Z_1$ and the relative axes $\varepsilon_2, \dots, \varepsilon_n$.

        **Returns:**

        The rotations, shape `(n, 3, 3)`.
        """
        return _bases_of_universal_joints(X.rotations[0], X.unit_vectors)

    def universal_joint_state(
        self, Z: Float[Array, "n 3 3"], omega: Float[Array, "n 3"]
    ) -> tuple[TensorCoordinates, TensorVelocities]:
        r"""The state of `in_universal_joints()` whose bodies have the rotations `Z` (which the
        joints must allow) and the angular velocities `omega`: $\varepsilon_k =
        Z_{k-1}^Te^{(k)}$ and its angular velocity $Z_{k-1}^T(\omega_k - \omega_{k-1})$.

        **Arguments:**

        - `Z`: the bodies' rotations, shape `(n, 3, 3)`; `omega`: their angular velocities,
          shape `(n, 3)`.

        **Returns:**

        `(X, V)`.
        """
        parents = Z[:-1]
        axes = jnp.einsum("kji,kj->ki", parents, Z[1:, :, 2])
        relative = jnp.einsum("kji,kj->ki", parents, omega[1:] - omega[:-1])
        scalars = jnp.zeros(0, Z.dtype)
        return (
            TensorCoordinates(scalars, axes, Z[:1]),
            TensorVelocities(scalars, relative, omega[:1]),
        )

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
        return self._balances(axes, axis_rates, axis_accelerations, omega, alpha)

    def _balances(self, axes, axis_rates, axis_accelerations, omega, alpha):
        r"""Per augmented body, the bracket of (59) and (60): $\tfrac{d}{dt}(J_k\omega_k) +
        e_k\times(\sum_{j\ne k}g_{kj}\ddot e_j + Mgb_ke_0)$."""
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

    def closed_form_universal_equations(
        self, X: TensorCoordinates, V: TensorVelocities, A: TensorVelocities
    ) -> tuple[Float[Array, "3"], Float[Array, "m 3"]]:
        r"""The left sides of the seed's (62), for `in_universal_joints()` at the rates $A$.

        With $S_k$ the bracket of (60) for body $k$: $\sum_k S_k$ (the equation of $Z_1$),
        and for $i \ge 2$ $\tilde e^{(i)}A_i^T\sum_{k \ge i}S_k$, with (61)'s
        $A_i = \frac{(u_i\cdot e^{(i)})}{|u_i\times e^{(i)}|}e^{(i)}e_1^{(i)T} + \tilde
        e^{(i)}$, $u_i$ the joint's first axis. (The seed prints the second with $\sum_{j >
        i}$ where (59) gives $\sum_{j\ne k}$; this is (59)'s.) The kinematics ($\omega_k$,
        $\dot\omega_k$, $\ddot e_k$) are differentiated from the bases; $\omega_k$ equals
        (61)'s sum.

        **Arguments:**

        - `X`, `V`, `A`: a state of `in_universal_joints()` and its velocities' rates.

        **Returns:**

        `(first, rest)`: the equation of $Z_1$, shape `(3,)`, and those of the axes in
        absolute axes, shape `(n - 1, 3)`.
        """
        Xdot, Xddot = rates_of(X, V), accelerations_of(X, V, A)
        position = (X.rotations[0], X.unit_vectors)
        rate = (Xdot.rotations[0], Xdot.unit_vectors)
        along = lambda x, v: jax.jvp(_bases_of_universal_joints, x, v)
        (Z, Zdot), (_, Zddot) = jax.jvp(
            along, (position, rate), (rate, (Xddot.rotations[0], Xddot.unit_vectors))
        )
        omega = angular_velocity(Z, Zdot)
        alpha = angular_velocity(Z, Zddot)  # (Z̈Zᵀ)^∨ of the skew part is ω̇
        balances = self._balances(Z @ _AXIS, Zdot @ _AXIS, Zddot @ _AXIS, omega, alpha)
        outboard = jnp.cumsum(balances[::-1], axis=0)[::-1]  # Σ_{k ≥ i}
        joint_axes = Z[:-1, :, 1]
        axes, first_axes = Z[1:, :, 2], Z[1:, :, 0]
        factor = jnp.sum(joint_axes * axes, axis=-1) / jnp.linalg.norm(
            jnp.cross(joint_axes, axes), axis=-1
        )
        # A_iᵀ v = factor (e·v) e₁ + ẽᵀ v = factor (e·v) e₁ - e × v
        sums = outboard[1:]
        transposed = factor[:, None] * jnp.sum(axes * sums, axis=-1, keepdims=True) * first_axes
        transposed = transposed - jnp.cross(axes, sums)
        return outboard[0], jnp.cross(axes, transposed)


def _kinetic_energy_of_rotations(chain, Z, Zdot):
    return chain.energies(Z @ _AXIS, Zdot @ _AXIS, angular_velocity(Z, Zdot))[0]


def _potential_energy_of_axes(chain, axes):
    return chain.energies(axes, jnp.zeros_like(axes), jnp.zeros_like(axes))[1]


class _InRotations(eqx.Module):
    chain: LagrangeGyroscopeChain

    def __call__(self, X, Xdot, t):
        return _kinetic_energy_of_rotations(self.chain, X.rotations, Xdot.rotations)


class _PotentialInRotations(eqx.Module):
    chain: LagrangeGyroscopeChain

    def __call__(self, X, t):
        return _potential_energy_of_axes(self.chain, X.rotations @ _AXIS)


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
        return _potential_energy_of_axes(self.chain, X.unit_vectors)


def _bases_of_universal_joints(first, relative_axes):
    r"""The rotations of a chain with universal joints from $Z_1$ and the axes $\varepsilon_k$
    in their parents' bases."""
    joint_axis = jnp.asarray([0.0, 1.0, 0.0], dtype=first.dtype)  # e₂ of the parent
    rotations = [first]
    for axis in relative_axes:
        across = jnp.cross(joint_axis, axis)
        first_axis = across / jnp.linalg.norm(across)
        local = jnp.stack([first_axis, jnp.cross(axis, first_axis), axis], axis=-1)
        rotations.append(rotations[-1] @ local)
    return jnp.stack(rotations)


class _InUniversalJoints(eqx.Module):
    chain: LagrangeGyroscopeChain

    def __call__(self, X, Xdot, t):
        Z, Zdot = jax.jvp(
            _bases_of_universal_joints,
            (X.rotations[0], X.unit_vectors),
            (Xdot.rotations[0], Xdot.unit_vectors),
        )
        return _kinetic_energy_of_rotations(self.chain, Z, Zdot)


class _PotentialInUniversalJoints(eqx.Module):
    chain: LagrangeGyroscopeChain

    def __call__(self, X, t):
        axes = _bases_of_universal_joints(X.rotations[0], X.unit_vectors) @ _AXIS
        return _potential_energy_of_axes(self.chain, axes)
