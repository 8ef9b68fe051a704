"""Solids: inertia formulas against numerical integration over the solid, inverse, errors."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import bundledyn as bd

SOLIDS = {
    "box": bd.Box((0.5, 0.3, 0.2)),
    "ellipsoid": bd.Ellipsoid((0.4, 0.25, 0.1)),
    "capsule": bd.Capsule(0.1, 0.35),
}


def _inside(solid, x):
    if isinstance(solid, bd.Box):
        return np.all(np.abs(x) <= 0.5 * np.asarray(solid.size), axis=-1)
    if isinstance(solid, bd.Ellipsoid):
        return np.sum((x / np.asarray(solid.radii)) ** 2, axis=-1) <= 1.0
    r, half = float(solid.radius), 0.5 * float(solid.length)
    along = np.clip(x[..., 0], -half, half)  # nearest point of the segment
    return (x[..., 0] - along) ** 2 + x[..., 1] ** 2 + x[..., 2] ** 2 <= r * r


def _integrated_inertia(solid, mass, n=161):
    """The inertia tensor of uniform density, by the midpoint rule on an n³ grid."""
    extent = np.max(np.abs(solid.surface(64)), axis=(0, 1)) * 1.001
    axes = [np.linspace(-e, e, n + 1) for e in extent]
    mids = [0.5 * (a[1:] + a[:-1]) for a in axes]
    x = np.stack(np.meshgrid(*mids, indexing="ij"), axis=-1).reshape(-1, 3)
    x = x[_inside(solid, x)]
    moments = np.einsum("ni,nj->ij", x, x) / len(x)
    return mass * (np.trace(moments) * np.eye(3) - moments)


@pytest.mark.parametrize("name", SOLIDS)
def test_inertia_is_that_of_the_uniform_solid(name):
    solid = SOLIDS[name]
    integrated = _integrated_inertia(solid, 2.0)
    np.testing.assert_allclose(np.diag(integrated), solid.principal_moments(2.0), rtol=5e-3)
    np.testing.assert_allclose(integrated - np.diag(np.diag(integrated)), 0.0, atol=1e-4)


def test_rigid_body_of_a_solid_sits_at_its_centre():
    body = SOLIDS["capsule"].rigid_body(3.0, com=(0.1, 0.0, -0.2))
    np.testing.assert_allclose(body.com, [0.1, 0.0, -0.2])
    np.testing.assert_allclose(np.diag(body.inertia), SOLIDS["capsule"].principal_moments(3.0))


@pytest.mark.parametrize("kind", [bd.Box, bd.Ellipsoid])
def test_equivalent_solid_has_the_given_moments(kind):
    moments = np.array([0.02, 0.05, 0.06])
    solid = kind.equivalent(1.5, moments)
    np.testing.assert_allclose(solid.principal_moments(1.5), moments, rtol=1e-12)


def test_capsule_moments_are_differentiable():
    grad = jax.grad(lambda r: jnp.sum(bd.Capsule(r, 0.3).principal_moments(1.0)))(0.1)
    eps = 1e-6
    fd = (
        jnp.sum(bd.Capsule(0.1 + eps, 0.3).principal_moments(1.0))
        - jnp.sum(bd.Capsule(0.1 - eps, 0.3).principal_moments(1.0))
    ) / (2 * eps)
    np.testing.assert_allclose(grad, fd, rtol=1e-7)


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: bd.Box((0.5, -0.1, 0.2)), "Box.size"),
        (lambda: bd.Box((0.5, 0.1)), "Box.size"),
        (lambda: bd.Ellipsoid((0.0, 1.0, 1.0)), "Ellipsoid.radii"),
        (lambda: bd.Capsule(0.1, float("nan")), "Capsule.length"),
    ],
)
def test_bad_solids_are_refused(make, message):
    with pytest.raises(ValueError, match=message):
        make()
