"""The result of a simulation: states at the saved times and the diagnostics users check first."""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from . import lie
from ._geometry import kinetic_energy
from ._scene import Scene
from ._term import SceneTerm


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
        term = SceneTerm(self.scene)

        def one(t, g, q, U, qdot):
            return term.kinematics(t, term.pack(g, q, U, qdot))

        return jax.vmap(one)(self.ts, self.g, self.q, self.U, self.qdot)

    # The diagnostics are compiled: evaluated op by op on a trajectory, the vmapped metric
    # of a 5-body chain compiled one kernel at a time (about 400, 9 s in all).
    @eqx.filter_jit
    def energy(self) -> Float[Array, " n"]:
        r"""Total energy in the Galilean frame: $T$ of (2.1) plus every conservative effect's $\Pi$."""
        scene = self.scene

        def one(kin):
            E = kinetic_energy(scene.system, kin.q, kin.xi, kin.qdot)
            for effect in scene.effects:
                Pi = effect.potential(scene.system, kin.t, kin.g, kin.q)
                if Pi is not None:
                    E = E + Pi
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
        return jnp.max(jnp.abs(jnp.swapaxes(R, -1, -2) @ R - jnp.eye(3)), axis=(-1, -2))
