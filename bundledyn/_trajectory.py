"""The result of a simulation: states at the saved times and the diagnostics users check first."""

import functools as ft
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from . import lie
from ._effects import AbstractPotential
from ._geometry import kinetic_energy
from ._modes import galilean_kinematics
from ._scene import Scene
from ._state import State


class Diagnostics(NamedTuple):
    """What users check first of a trajectory, each at every saved time: the energy and the
    spatial momentum in the Galilean frame, the rotations' orthogonality error and the
    residuals of the constraints the scene's mode keeps and the system eliminates (`r = 0`
    rows if none)."""

    energy: Float[Array, " n"]
    spatial_momentum: Float[Array, "n 6"]
    orthogonality_error: Float[Array, " n"]
    constraint_residual: Float[Array, "n r"]


class Trajectory(eqx.Module):
    r"""States at the saved times, in the scene's frame, with diagnostics.

    Arrays carry a leading time axis; with `SaveAt(t1=True)` (or any save including
    `t1`), the last entry is the state at `t1`. Entries past the last step of a
    `SaveAt(steps=True)` solve are padded with `inf`, as diffrax does.

    **Fields:** `ts` `(n,)`, `g` `(n, 4, 4)` (section frame pose), `q`, `qdot` `(n, d)`,
    `xi` `(n, 6)` ($g^{-1}\dot g$), `U` `(n, 6)` (locked velocity), `stats` (diffrax's solver
    statistics: steps, accepted and rejected steps, vector-field evaluations), `result`
    (diffrax's result code), `scene`.
    """

    ts: Float[Array, " n"]
    g: Float[Array, "n 4 4"]
    q: Float[Array, "n d"]
    xi: Float[Array, "n 6"]
    qdot: Float[Array, "n d"]
    U: Float[Array, "n 6"]
    stats: dict
    result: object
    scene: Scene

    def _kinematics(self):
        """The saved states in the Galilean frame, from the decoded states (no re-encoding)."""
        return jax.vmap(ft.partial(galilean_kinematics, self.scene))(
            self.ts, self.g, self.q, self.xi, self.qdot
        )

    # The diagnostics are compiled: evaluated op by op on a trajectory, the vmapped metric
    # is compiled one kernel at a time, each a program of its own.
    @eqx.filter_jit
    def energy(self) -> Float[Array, " n"]:
        r"""Total energy in the Galilean frame: $T$ of (2.1) plus every conservative effect's $\Pi$."""
        scene = self.scene

        def one(kin):
            E = kinetic_energy(scene.system, kin.q, kin.xi, kin.qdot)
            for effect in scene.effects:
                if isinstance(effect, AbstractPotential):
                    E = E + effect.potential(scene.system, kin.t, kin.g, kin.q)
            return E

        return jax.vmap(one)(self._kinematics())

    @eqx.filter_jit
    def spatial_momentum(self) -> Float[Array, "n 6"]:
        r"""The momentum $\operatorname{Ad}^*_g I_r U$ in the Galilean frame (about its origin).

        Conserved when no external force acts (seed 004, (2.6) with $\mathbf F = 0$).
        """
        system = self.scene.system

        def one(kin):
            # Body momentum of the section frame: I_r ξ + B q̇ = I_r U.
            p = system.metric(kin.q)[:6] @ jnp.concatenate([kin.xi, kin.qdot])
            return lie.coAd(kin.g) @ p

        return jax.vmap(one)(self._kinematics())

    @eqx.filter_jit
    def orthogonality_error(self) -> Float[Array, " n"]:
        r"""$\max_{ij}|R^TR - 1|$ of the section frame's rotation at every saved time."""
        R = self.g[:, :3, :3]
        identity = jnp.broadcast_to(jnp.eye(3, dtype=R.dtype), R.shape)
        return jnp.max(jnp.abs(jnp.swapaxes(R, -1, -2) @ R - identity), axis=(-1, -2))

    @eqx.filter_jit
    def diagnostics(self) -> Diagnostics:
        """`energy`, `spatial_momentum`, `orthogonality_error` and `constraint_residual` in
        one compiled program, for a caller that reads them all (the command line's summary,
        files and plots)."""
        return Diagnostics(
            self.energy(),
            self.spatial_momentum(),
            self.orthogonality_error(),
            self.constraint_residual(),
        )

    @eqx.filter_jit
    def constraint_residual(self) -> Float[Array, "n r"]:
        """The residuals of the constraints the scene's mode keeps (`AbstractMode.constraint_residual`:
        a rolling body's contact velocity and height), then those the system eliminates
        (`AbstractSystem.constraint_residual`: a `ConstrainedSystem`'s $f(q)$), at every saved
        time; `r = 0` if none."""
        mode, scene = self.scene.mode, self.scene

        def residual(g, q, xi, qdot):
            kept = mode.constraint_residual(scene, State(g, q, xi, qdot))
            return jnp.concatenate([kept, scene.system.constraint_residual(q).astype(kept.dtype)])

        return jax.vmap(residual)(self.g, self.q, self.xi, self.qdot)
