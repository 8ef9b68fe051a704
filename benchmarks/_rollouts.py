"""Rollouts from a state whose base twist varies: the loss both gradient benchmarks
differentiate, and `jax.vmap`ped batches over twists."""

import bundledyn as bd


def with_twist(state: bd.State, xi) -> bd.State:
    """`state` with the base twist `xi`."""
    return bd.State(state.g, state.q, xi, state.qdot)


def rollout_loss(scene, state, t1, **options):
    r"""`xi -> |p(t_1)|^2 + |q(t_1)|^2`: the squared final position of the base and shape of
    `bd.simulate(scene, with_twist(state, xi), t1, **options)`."""
    import jax.numpy as jnp

    def loss(xi):
        traj = bd.simulate(scene, with_twist(state, xi), t1, **options)
        return jnp.sum(traj.g[-1, :3, 3] ** 2) + jnp.sum(traj.q[-1] ** 2)

    return loss


def batch_rollouts(scene, state, t1, **options):
    """A jitted `xi -> (final poses, steps)`: `jax.vmap` of `bd.simulate` from `state` with
    each base twist of the batch `xi`, `(batch, 6)`."""
    import jax

    @jax.jit
    def run(xi):
        def one(x):
            traj = bd.simulate(scene, with_twist(state, x), t1, **options)
            return traj.g[-1], traj.stats["num_steps"]

        return jax.vmap(one)(xi)

    return run
