"""The Whipple bicycle as a tree on two rolling wheels: sympy's model (as in `bicycle`)
against bundledyn's shipped scene `bundledyn/scenes/bicycle.toml` (the paper's bicycle from
MJCF, `RollingWheelMode`: Maggi's equations as Gauss's principle with the tree's metric, the
rear frame's pose on SE(3), `simulate`'s `RKMK87`).

The members, the peer and the comparison are `bicycle`'s. A member's initial state is the
tree's state of `WhippleBicycle`'s (the rear frame's pose and the velocities its rolling
constraints give), and the tree's trajectory is read back as the paper's angles: the rear
frame's rotation is $R_z(\\psi)R_x(\\phi)R_y(\\theta_B)$, the steer is the tree's second
shape coordinate."""

import functools

import numpy as np

from benchmarks.nonholonomic.bicycle import _to_peer, disagreement, kane_model, members

__all__ = ["NAME", "disagreement", "initial_states", "kane_model", "members", "ours_model"]

NAME = "Whipple bicycle as a tree"
# The tree's bodies: the rear frame (the base), the rear wheel, the front frame, the front
# wheel; `WhippleBicycle.placement` lists the rear wheel first, then the rear frame.
PLACED_REAR_WHEEL, PLACED_REAR_FRAME = 0, 1


def ours_model(variant=None):
    """The shipped scene `bicycle.toml`: `(scene, WhippleBicycle)`, the second for the states."""
    import bundledyn as bd

    return bd.SceneFile.load(bd.scenes / "bicycle.toml").scene, bd.WhippleBicycle.benchmark()


def initial_states(model, speeds, member):
    """`(the tree's State, the peer's state)` of a member: `WhippleBicycle`'s upright running
    at its speed, leaning and steered, in the tree's variables."""
    import jax
    import jax.numpy as jnp

    import bundledyn as bd
    from benchmarks.nonholonomic import bicycle

    scene, bike = model
    (q, e), x0 = bicycle.initial_states(bike, speeds, member)
    qdot = bd.constrained_velocities(bike.constraints, q, e, 0.0)
    placed, moving = jax.jvp(bike.placement, (q,), (qdot,))
    R, R_dot = placed.rotations[PLACED_REAR_FRAME], moving.rotations[PLACED_REAR_FRAME]
    g = jnp.eye(4).at[:3, :3].set(R).at[:3, 3].set(placed.centres[PLACED_REAR_WHEEL])
    shape = jnp.stack([q[6] - q[4], q[5], q[7]])
    omega = bd.lie.so3_vee(R.T @ R_dot)
    e_tree = jnp.stack([omega[0], qdot[6] - qdot[4], qdot[5]])  # independent = (0, 6, 7)
    return scene.mode.state(scene.system, g, shape, e_tree), x0


@functools.cache
def _solver():
    """The compiled solve (made once), returning the saved poses, shapes and velocities."""
    import diffrax
    import equinox as eqx

    import bundledyn as bd

    @eqx.filter_jit
    def solve(scene, state, ts, rtol):
        traj = bd.simulate(
            scene, state, ts[-1], t0=ts[0], rtol=rtol, atol=rtol, max_steps=100_000,
            saveat=diffrax.SaveAt(ts=ts),
        )  # fmt: skip
        return traj.g, traj.q, traj.xi, traj.qdot

    return solve


def _angles(R):
    """$(\\psi, \\phi, \\theta_B)$ of $R = R_z(\\psi)R_x(\\phi)R_y(\\theta_B)$."""
    import jax.numpy as jnp

    return jnp.stack(
        [
            jnp.arctan2(-R[0, 1], R[1, 1]),
            jnp.arcsin(R[2, 1]),
            jnp.arctan2(-R[2, 0], R[2, 2]),
        ]
    )


def _paper_state(g, shape, xi, shape_rate):
    """The paper's $(q, \\dot q)$ (the compared parts: yaw, roll, pitch, steer and their
    rates; the positions and wheel angles left zero) of one saved tree state."""
    import jax
    import jax.numpy as jnp

    import bundledyn as bd

    R = g[:3, :3]
    angles, rates = jax.jvp(_angles, (R,), (R @ bd.lie.so3_hat(xi[:3]),))
    zero = jnp.zeros_like(angles[0])
    q = jnp.stack([zero, zero, *angles, shape[1], zero, zero])
    qdot = jnp.stack([zero, zero, *rates, shape_rate[1], zero, zero])
    return q, qdot


def simulate(model, state, ts, rtol):
    """bundledyn's trajectory at `ts`, as the peer's states `(n, 10)` (only the compared
    columns are meaningful)."""
    import jax

    scene, _ = model
    g, shape, xi, shape_rate = _solver()(scene, state, ts, rtol)
    q, qdot = jax.vmap(_paper_state)(g, shape, xi, shape_rate)
    return _to_peer(np.asarray(q), np.asarray(qdot))
