r"""The coordinates of an identification window's initial state, one chart per layout.

A window state $s$ is what multiple shooting fits at each window's start: the whole state
about a reference pose for a floating base, the shape and its velocity for a given base.
"""

import abc
from typing import Any, Protocol

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import lie
from .._state import State
from .._systems._ball_chart import ball_columns, shape_difference, shape_velocity_difference

__all__ = ["AbstractWindowChart", "ChannelScales", "DrivenChart", "FloatingChart", "balls_of"]


def balls_of(system) -> tuple[tuple[int, ...], ...]:
    """The ball joints' shape coordinates of `system`, as a chart's static field."""
    return tuple(tuple(row) for row in ball_columns(system).tolist())


class ChannelScales(Protocol):
    """A scale per measured channel (the identification's noise levels)."""

    @property
    def rotation(self) -> Any: ...

    @property
    def position(self) -> Any: ...

    @property
    def q(self) -> Any: ...

    @property
    def angular_velocity(self) -> Any: ...

    @property
    def linear_velocity(self) -> Any: ...

    @property
    def qdot(self) -> Any: ...


class AbstractWindowChart(eqx.Module):
    """Coordinates $s$ of a window's initial state."""

    d: eqx.AbstractVar[int]
    balls: eqx.AbstractVar[tuple[tuple[int, ...], ...]]

    def shape_differences(self, end: State, start: State) -> tuple[jax.Array, jax.Array]:
        """`end - start` of the shape and of its velocity, ball joints compared by their
        rotation and angular velocity (the same in every chart of their coordinates)."""
        columns = np.asarray(self.balls, dtype=int).reshape(-1, 3)
        return shape_difference(columns, end.q, start.q), shape_velocity_difference(
            columns, end.q, end.qdot, start.q, start.qdot
        )

    @property
    @abc.abstractmethod
    def size(self) -> int:
        """The number of coordinates of $s$."""

    @abc.abstractmethod
    def state(self, s, g_ref) -> State:
        """The `State` of the coordinates `s` about the reference pose `g_ref`."""

    @abc.abstractmethod
    def coordinates(self, q, xi, qdot) -> jax.Array:
        r"""$s$ of states at their own reference poses, batched over windows."""

    @abc.abstractmethod
    def units(self, scales: ChannelScales) -> jax.Array:
        """Each coordinate's natural unit: its channel's scale."""

    @abc.abstractmethod
    def difference(self, end: State, start: State, scales: ChannelScales) -> jax.Array:
        """`end - start` in the chart, each part divided by its channel's scale."""


class FloatingChart(AbstractWindowChart):
    r"""Window states of a floating base: $s = (\delta, q, \xi, \dot q)$ about a reference
    pose $\bar g$, the pose being $\bar g\exp\hat\delta$."""

    d: int = eqx.field(static=True)
    balls: tuple[tuple[int, ...], ...] = eqx.field(static=True, default=())

    @property
    def size(self) -> int:
        return 12 + 2 * self.d

    def state(self, s, g_ref) -> State:
        d = self.d
        return State(g_ref @ lie.se3_exp(s[:6]), s[6 : 6 + d], s[6 + d : 12 + d], s[12 + d :])

    def coordinates(self, q, xi, qdot):
        return jnp.concatenate([jnp.zeros_like(xi), q, xi, qdot], axis=-1)

    def units(self, scales: ChannelScales):
        d = self.d
        return jnp.concatenate(
            [
                jnp.full(3, scales.rotation), jnp.full(3, scales.position), jnp.full(d, scales.q),
                jnp.full(3, scales.angular_velocity), jnp.full(3, scales.linear_velocity),
                jnp.full(d, scales.qdot),
            ]
        )  # fmt: skip

    def difference(self, end: State, start: State, scales: ChannelScales):
        q, qdot = self.shape_differences(end, start)
        difference = jnp.concatenate(
            [
                lie.so3_log(start.g[:3, :3].T @ end.g[:3, :3]), end.g[:3, 3] - start.g[:3, 3],
                q, end.xi - start.xi, qdot,
            ]
        )  # fmt: skip
        return difference / self.units(scales)


class DrivenChart(AbstractWindowChart):
    r"""Window states of a given base: $s = (q, \dot q)$ (the base's motion is known)."""

    d: int = eqx.field(static=True)
    balls: tuple[tuple[int, ...], ...] = eqx.field(static=True, default=())

    @property
    def size(self) -> int:
        return 2 * self.d

    def state(self, s, g_ref) -> State:
        return State(g_ref, s[: self.d], jnp.zeros(6, s.dtype), s[self.d :])

    def coordinates(self, q, xi, qdot):
        return jnp.concatenate([q, qdot], axis=-1)

    def units(self, scales: ChannelScales):
        return jnp.concatenate([jnp.full(self.d, scales.q), jnp.full(self.d, scales.qdot)])

    def difference(self, end: State, start: State, scales: ChannelScales):
        difference = jnp.concatenate(self.shape_differences(end, start))
        return difference / self.units(scales)
