"""Systems that are not acceptable mechanical models: each breaks Theorem 2.2 on purpose.

They are `GenericSystem`s with a kinetic energy written by hand, for tests and teaching:
`galilean_invariance` flags each by the condition it breaks, and simulations of them in a
boosted frame disagree with the Galilean ones.

A system that breaks (c) and nothing else does not exist on an open set of shapes: if (a)
and (b) hold near $s$, the centre of mass is constant along horizontal curves, hence along
their brackets, whose vertical parts are the curvature values; so every curvature value
fixes $c_s$, which is (c) by Theorem 2.3. `translational_curvature` therefore breaks (b) as
well, except at its symmetric shape $q = 0$, where (c) alone fails.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._systems._generic import GenericSystem

# NumPy, not JAX: importing bundledyn must not start JAX's backend (`use_cpu_xla_flags`).
_ROTATIONAL_INERTIA = np.array([[0.4, 0.02, 0.0], [0.02, 0.5, -0.03], [0.0, -0.03, 0.7]])


def _rotational(xi):
    return 0.5 * xi[:3] @ _ROTATIONAL_INERTIA @ xi[:3]


class _AnisotropicMassEnergy(eqx.Module):
    masses: Float[Array, "3"]

    def __call__(self, q, qdot, xi):
        return _rotational(xi) + 0.5 * xi[3:] @ (self.masses * xi[3:]) + 0.5 * qdot @ qdot


class _ShapeDependentMassEnergy(eqx.Module):
    variation: Float[Array, ""]

    def __call__(self, q, qdot, xi):
        mass = 1.0 + self.variation * jnp.tanh(q[0])
        return _rotational(xi) + 0.5 * mass * xi[3:] @ xi[3:] + 0.5 * qdot @ qdot


class _DriftingCentreEnergy(eqx.Module):
    drift: Float[Array, "3"]

    def __call__(self, q, qdot, xi):
        centre = self.drift * jnp.sin(q[0])
        velocity_of_centre = xi[3:] + jnp.cross(xi[:3], centre)
        return _rotational(xi) + 0.5 * velocity_of_centre @ velocity_of_centre + 0.5 * qdot @ qdot


class _TranslationalCurvatureEnergy(eqx.Module):
    strength: Float[Array, ""]

    def __call__(self, q, qdot, xi):
        # The connection A(q) q̇ = (0, k/2 (q1 q̇2 - q2 q̇1) e_x) has curl k e_x: a translation.
        swept = 0.5 * self.strength * (q[0] * qdot[1] - q[1] * qdot[0])
        U = xi.at[3].add(swept)
        return _rotational(U) + 0.5 * U[3:] @ U[3:] + 0.5 * qdot @ qdot


def anisotropic_mass(masses=(1.0, 2.0, 3.0)) -> GenericSystem:
    r"""A body whose translational mass depends on the direction: breaks (a) only.

    $T = \tfrac12\omega^T l\,\omega + \tfrac12 v^T\operatorname{diag}(m_1, m_2, m_3)v + \tfrac12\dot q^2$
    in body axes. Its locked inertia is not of the rigid form of Lemma 1, so the inertial forces
    of the frozen system are not objective: $\mathbf C(U, X) \ne 0$. One decoupled shape
    coordinate keeps (b) and (c) meaningful; they hold.
    """
    return GenericSystem(_AnisotropicMassEnergy(jnp.asarray(masses, dtype=float)), 1)


def shape_dependent_mass(variation=0.5) -> GenericSystem:
    r"""A rigid-form body whose mass changes with its shape: breaks (b) only (Lemma 2).

    $T = \tfrac12\omega^T l\,\omega + \tfrac12 m(q)|v|^2 + \tfrac12\dot q^2$ with
    $m(q) = 1 + \text{variation}\cdot\tanh q$. The frozen system is a rigid body, but $m$ is
    not constant on $\mathbb S$.
    """
    return GenericSystem(_ShapeDependentMassEnergy(jnp.asarray(variation, dtype=float)), 1)


def drifting_centre(drift=(0.3, 0.1, 0.0)) -> GenericSystem:
    r"""A rigid-form body whose centre of mass moves when the shape changes at zero momentum: breaks (b) only.

    $T = \tfrac12\omega^T l\,\omega + \tfrac12|v + \omega\times c(q)|^2 + \tfrac12\dot q^2$ with
    $c(q) = \text{drift}\cdot\sin q$ and no shape–group coupling, so every shape change is
    horizontal and carries $c_s$ along (property 2 of Theorem 2.3 fails).
    """
    return GenericSystem(_DriftingCentreEnergy(jnp.asarray(drift, dtype=float)), 1)


def translational_curvature(strength=1.0) -> GenericSystem:
    r"""A rigid-form body whose connection has a translational curvature: breaks (c), and (b) off $q = 0$.

    $T = \tfrac12 U^T I U + \tfrac12|\dot q|^2$ with $U = \xi + A(q)\dot q$, $I$ a rigid
    inertia with centre at the origin and $A(q)\dot q = (0, \tfrac k2(q_1\dot q_2 - q_2\dot
    q_1)e_x)$: a small shape loop at zero momentum translates the body by $-k\,e_x$ times its
    area, so $\Omega(e_1, e_2) = (0, k\,e_x)\notin\mathfrak c_s$. See the module docstring for why
    (c) cannot fail alone on an open set.
    """
    return GenericSystem(_TranslationalCurvatureEnergy(jnp.asarray(strength, dtype=float)), 2)
