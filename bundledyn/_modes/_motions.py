r"""The motions a user gives a scene's shape and base: free, or prescribed as functions of time."""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp

from .. import lie

__all__ = ["FloatingBase", "Free", "Prescribed", "PrescribedBase"]


class Free(eqx.Module):
    """The shape moves dynamically: both equations (2.6) are integrated."""


class FloatingBase(eqx.Module):
    """The section frame moves freely: (2.7) is integrated (the default)."""


class Prescribed(eqx.Module):
    r"""The shape follows a given motion $q(t)$ (kinematic shape control).

    Only (2.7) for the locked velocity and the reconstruction $\xi = U - A\dot q$ are
    integrated: the falling cat, a satellite moving its arm.

    **Arguments:**

    - `q_of_t`: a JAX function `t -> q (d,)`; $\dot q$ and $\ddot q$ come by autodiff.
    """

    q_of_t: Callable

    def at(self, t):
        r"""$(q, \dot q)$ at time `t`."""
        return jax.jvp(self.q_of_t, (t,), (jnp.ones_like(t),))


class PrescribedBase(eqx.Module):
    r"""The section frame follows a given motion $g(t)$: a fixed base, or one moving like a
    ship's deck; only the shape equation is integrated, driven by the base's motion (the
    dual of `Prescribed`). The base's motion is given in the Galilean frame.

    **Arguments:**

    - `g_of_t`: a JAX function `t -> g (4, 4)`, a pose in SE(3) for every $t$; its body
      velocity $\xi = (g^{-1}\dot g)^\vee$ and $\dot\xi$ come by autodiff.
    """

    g_of_t: Callable

    @classmethod
    def fixed(cls, g=None) -> "PrescribedBase":
        """A base held still at the pose `g` (default the identity)."""
        pose = jnp.eye(4) if g is None else jnp.asarray(g, dtype=float)
        return cls(_Constant(pose))

    def at(self, t):
        r"""$(g, \xi, \dot\xi)$ at time `t`."""

        def velocity(t):
            g, g_dot = jax.jvp(self.g_of_t, (t,), (jnp.ones_like(t),))
            return lie.vee(lie.se3_inv(g) @ g_dot)

        xi, xi_dot = jax.jvp(velocity, (t,), (jnp.ones_like(t),))
        return self.g_of_t(t), xi, xi_dot


class _Constant(eqx.Module):
    value: jax.Array

    def __call__(self, t):
        return self.value + 0.0 * t
