"""The family: chains of 2 to 4 gyroscopes with random bodies and random spinning starts, one
model each for the tensor formulations, `Multibody.from_mjcf` and MuJoCo."""

import numpy as np


def members(quick):
    """`[{"label", "size", "seed"}]`: sizes 2, 3, 4 and two seeds each (one three-body chain
    when quick)."""
    grid = [(3, 0)] if quick else [(n, seed) for n in (2, 3, 4) for seed in (0, 1)]
    return [{"label": f"{n} bodies, seed {seed}", "size": n, "seed": seed} for n, seed in grid]


def chain(member):
    """The member's `LagrangeGyroscopeChain`: masses 0.5–1.5 kg, lengths 0.25–0.45 m, centres
    at 0.4–0.6 of them, inertias of a spinning disc-like body."""
    import bundledyn as bd

    rng = np.random.default_rng(member["seed"] * 10 + member["size"])
    n = member["size"]
    masses = rng.uniform(0.5, 1.5, n)
    lengths = rng.uniform(0.25, 0.45, n)
    centres = rng.uniform(0.4, 0.6, n) * lengths
    axial = masses * rng.uniform(0.004, 0.008, n)
    return bd.LagrangeGyroscopeChain(masses, lengths, centres, 1.6 * axial, axial)


def start(member):
    """`(X, V)` in the rotation tensors: bodies tilted by up to 0.5 rad, spinning at 15–40
    rad/s about their axes with a slower tumble."""
    import jax.numpy as jnp

    import bundledyn as bd
    from bundledyn import lie

    rng = np.random.default_rng(member["seed"] * 10 + member["size"] + 5)
    n = member["size"]
    Z = lie.so3_exp(jnp.asarray(rng.uniform(-0.5, 0.5, (n, 3))))
    body_rates = np.column_stack(
        [rng.normal(0.0, 0.5, (n, 2)), rng.choice([-1, 1], n) * rng.uniform(15, 40, n)]
    )
    omega = jnp.einsum("kij,kj->ki", Z, jnp.asarray(body_rates))
    scalars, vectors = jnp.zeros(0), jnp.zeros((0, 3))
    return bd.TensorCoordinates(scalars, vectors, Z), bd.TensorVelocities(scalars, vectors, omega)
