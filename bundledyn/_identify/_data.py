r"""Measured motion and known inputs: what an identification is fitted to.

`Measurements` holds sample times and any subset of the channels a lab records of a
floating system — the section frame's pose (motion capture), the shape coordinates (joint
encoders), the section frame's body twist (gyros, and a linear velocity where one is
measured), the shape velocities, the poses of chosen bodies — each with its noise level
(one standard deviation). `Inputs` holds the known forces that drove the motion — joint
torques, external wrenches (thrusters) — as sampled time series, which enter the scene as
effects through diffrax's interpolations.
"""

import pathlib

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._effects import AbstractEffect, ExternalWrench, ShapeForce
from .._state import State
from .._systems._mujoco_state import state_from_mujoco
from .._systems._multibody import AbstractMultibody

__all__ = ["Inputs", "Measurements", "Noise", "body_frame_velocity_noise"]

_CHANNELS = ("pose", "q", "xi", "qdot", "body_poses")


Level = float | np.ndarray | jax.Array


def level(value: Level) -> Level:
    """A number held as an array leaf: `eqx.filter_jit` traces arrays but keys its cache on
    Python floats, so a float field would compile anew for every new value (noise level,
    known mass, continuity weight)."""
    return value if isinstance(value, jax.Array) else np.asarray(value, dtype=float)


def _level_field(default: float):
    return eqx.field(default=default, converter=level)


class Noise(eqx.Module):
    r"""Standard deviations of the measurement channels, in the system's units.

    **Arguments:**

    - `rotation`: of the measured orientations (radians, per axis).
    - `position`: of the measured positions (length).
    - `q`: of the shape coordinates (radians for hinges, length for slides).
    - `angular_velocity`, `linear_velocity`: of the twist's two parts.
    - `qdot`: of the shape velocities.

    A channel that is measured needs a positive level: it is the weight $1/\sigma$ of its
    residuals, and the scale of the confidence intervals.
    """

    rotation: Level = _level_field(1.0)
    position: Level = _level_field(1.0)
    q: Level = _level_field(1.0)
    angular_velocity: Level = _level_field(1.0)
    linear_velocity: Level = _level_field(1.0)
    qdot: Level = _level_field(1.0)


def body_frame_velocity_noise(noise: Noise, v_body) -> Noise:
    r"""`noise` (its linear velocity's level that of a world-frame velocity) with the level
    of the body-frame linear velocity $R^Tv$ computed with a measured orientation.

    An orientation off by $\delta\phi$ (level $\sigma_R$ per axis) turns $v_b$ by
    $-\delta\phi\times v_b$: per component, variance $\sigma_R^2(|v_b|^2 - v_{b,i}^2)$,
    $\tfrac23\sigma_R^2|v_b|^2$ on average. The level returned is
    $\sqrt{\sigma_v^2 + \tfrac23\sigma_R^2\,\overline{|v_b|^2}}$, the mean over the samples.

    **Arguments:**

    - `noise`: the levels as recorded; `v_body`: the body-frame linear velocities, `(n, 3)`.

    **Returns:**

    The `Noise` with `linear_velocity` replaced.
    """
    mean_square = jnp.mean(jnp.sum(jnp.square(v_body), axis=-1))
    combined = jnp.sqrt(noise.linear_velocity**2 + (2 / 3) * noise.rotation**2 * mean_square)
    return eqx.tree_at(lambda n: n.linear_velocity, noise, np.asarray(combined))


class Measurements(eqx.Module):
    r"""Measured motion at sample times, each channel optional.

    **Arguments:**

    - `ts`: sample times, increasing, shape `(n,)`.
    - `pose`: the section frame's pose $g$ in the Galilean frame, `(n, 4, 4)`.
    - `q`: the shape coordinates, `(n, d)`.
    - `xi`: the section frame's body twist $\xi = g^{-1}\dot g$ (angular first), `(n, 6)`.
    - `qdot`: the shape velocities, `(n, d)`.
    - `body_poses`: poses of the bodies `bodies` in the Galilean frame, `(n, k, 4, 4)`.
    - `bodies`: indices of the bodies whose poses are measured (static).
    - `noise`: the channels' `Noise`.
    """

    ts: Float[Array, " n"]
    pose: Float[Array, "n 4 4"] | None = None
    q: Float[Array, "n d"] | None = None
    xi: Float[Array, "n 6"] | None = None
    qdot: Float[Array, "n d"] | None = None
    body_poses: Float[Array, "n k 4 4"] | None = None
    bodies: tuple[int, ...] = eqx.field(static=True, default=())
    noise: Noise = Noise()

    def __check_init__(self):
        ts = np.asarray(self.ts)
        if ts.ndim != 1 or ts.size < 2 or not np.all(np.diff(ts) > 0):
            raise ValueError("`Measurements.ts` must be at least two increasing sample times.")
        present = self.channels
        if not present:
            raise ValueError(
                "`Measurements` holds no channel: give at least one of " + ", ".join(_CHANNELS)
            )
        for name in present:
            if np.shape(getattr(self, name))[0] != ts.size:
                raise ValueError(f"`Measurements.{name}` must have {ts.size} samples (one per ts).")
        if (self.body_poses is None) != (not self.bodies):
            raise ValueError("give `body_poses` and the indices `bodies` of those bodies together.")

    @property
    def channels(self) -> tuple[str, ...]:
        """The names of the measured channels."""
        return tuple(name for name in _CHANNELS if getattr(self, name) is not None)

    @property
    def states(self) -> State | None:
        r"""The measured states $(g, q, \xi, \dot q)$ at every sample (a batched `State`),
        or `None` unless the pose, twist, shape and shape velocity are all measured."""
        if self.pose is None or self.xi is None or self.q is None or self.qdot is None:
            return None
        return jax.vmap(State)(self.pose, self.q, self.xi, self.qdot)

    @classmethod
    def from_states(cls, ts, states: State, *, noise: Noise, channels=("pose", "q", "xi", "qdot")):
        """Measurements of the chosen channels of a batch of states (a simulated or
        estimated trajectory, e.g. `Trajectory` fields).

        **Arguments:**

        - `ts`: sample times, `(n,)`; `states`: a `State` batched over them.
        - `noise`: the `Noise` levels; `channels`: which of pose, q, xi, qdot to keep.
        """
        fields = {"pose": states.g, "q": states.q, "xi": states.xi, "qdot": states.qdot}
        unknown = set(channels) - set(fields)
        if unknown:
            raise ValueError(f"unknown channels {sorted(unknown)}; use pose, q, xi or qdot.")
        kept = {name: jnp.asarray(fields[name]) for name in channels}
        # `bodies` given (its default) so that the unpacked channels cannot be taken for it.
        return cls(jnp.asarray(ts, dtype=float), bodies=(), noise=noise, **kept)

    @classmethod
    def from_mujoco(
        cls,
        system: AbstractMultibody,
        ts,
        qpos,
        qvel,
        *,
        noise: Noise,
        qpos0=None,
        channels=("pose", "q", "xi", "qdot"),
    ):
        """Measurements from MuJoCo's `qpos`, `qvel` at sample times (a rollout, or a lab's
        log written in MuJoCo's layout), through `bundledyn.state_from_mujoco`.

        `noise` states the levels of the record as written, MuJoCo's layout: the free
        joint's linear velocity in the world frame. The body-frame twist is that velocity
        turned by the measured orientation, so its linear part carries the orientation's
        noise too: where the pose is measured, its level is raised to the root mean square
        of both (`body_frame_velocity_noise`).

        **Arguments:**

        - `system`: the imported tree; `ts`: `(n,)`; `qpos`, `qvel`: `(n, nq)`, `(n, nv)`.
        - `noise`, `channels`: as in `from_states`; `qpos0`: MuJoCo's `model.qpos0`.
        """
        to_state = jax.vmap(lambda p, v: state_from_mujoco(system, p, v, qpos0=qpos0))
        states = to_state(jnp.asarray(qpos, dtype=float), jnp.asarray(qvel, dtype=float))
        if "pose" in channels and "xi" in channels:
            noise = body_frame_velocity_noise(noise, states.xi[:, 3:])
        return cls.from_states(ts, states, noise=noise, channels=channels)

    def save(self, path) -> None:
        """Write the measurements to an `.npz` file (`load` reads it back)."""
        arrays = {name: np.asarray(getattr(self, name)) for name in self.channels}
        noise = {f"noise_{k}": np.asarray(v) for k, v in vars(self.noise).items()}
        fields = {"ts": np.asarray(self.ts), "bodies": np.asarray(self.bodies, int)}
        # numpy's stub lets unpacked keys reach `allow_pickle`; these are only array names.
        np.savez(path, **fields, **arrays, **noise)  # pyright: ignore[reportArgumentType]

    @classmethod
    def load(cls, path) -> "Measurements":
        """Read measurements written by `save` (or any `.npz` with the same keys: `ts`, the
        channels `pose`, `q`, `xi`, `qdot`, `body_poses` with `bodies`, and `noise_*`)."""
        with np.load(pathlib.Path(path)) as archive:
            data = {key: archive[key] for key in archive.files}
        noise = Noise(**{k[6:]: float(v) for k, v in data.items() if k.startswith("noise_")})
        channels = {name: jnp.asarray(data[name]) for name in _CHANNELS if name in data}
        bodies = tuple(int(b) for b in data.get("bodies", ()))
        return cls(jnp.asarray(data["ts"]), bodies=bodies, noise=noise, **channels)

    @classmethod
    def from_csv(cls, path, system: AbstractMultibody, *, noise: Noise, qpos0=None, **kwargs):
        """Measurements from a CSV file of MuJoCo-layout rows: a header, then `t`, the
        `qpos` columns and the `qvel` columns (any names; read in that order).

        **Arguments:**

        - `path`: the file; `system`: the imported tree (it fixes `nq` and `nv`).
        - `noise`, `qpos0`, `channels`: as in `from_mujoco`.
        """
        table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        nq = 7 + sum(4 if k == "ball" else 1 for k in system.tables.kinds if k in ("ball", "screw"))
        nv = 6 + system.shape_dim
        if table.shape[1] != 1 + nq + nv:
            raise ValueError(
                f"{path}: {table.shape[1]} columns; this system needs 1 + {nq} + {nv} "
                "(t, qpos, qvel)."
            )
        return cls.from_mujoco(
            system, table[:, 0], table[:, 1 : 1 + nq], table[:, 1 + nq :], noise=noise,
            qpos0=qpos0, **kwargs,
        )  # fmt: skip


class _Interpolated(eqx.Module):
    """A sampled time series as a function of time: the effects' `fn`."""

    interpolation: diffrax.AbstractPath

    def value(self, t):
        return self.interpolation.evaluate(t)


class _JointForce(_Interpolated):
    def __call__(self, t, q, qdot):
        return self.value(t)


class _BodyWrench(_Interpolated):
    def __call__(self, t, g, q, xi, qdot):
        return self.value(t)


def _interpolate(ts, values, kind):
    ts, values = jnp.asarray(ts, dtype=float), jnp.asarray(values, dtype=float)
    if kind == "linear":
        return diffrax.LinearInterpolation(ts, values)
    return diffrax.CubicInterpolation(ts, diffrax.backward_hermite_coefficients(ts, values))


class Inputs(eqx.Module):
    r"""Known forces that drove the motion, sampled in time; they enter the scene as effects.

    **Arguments:**

    - `ts`: sample times of the inputs, increasing, `(m,)`.
    - `joint_forces`: the shape forces $Q_H$ (joint torques and forces, in the order of
      $q$), `(m, d)`: a `ShapeForce`.
    - `wrenches`: external wrenches $(\tau, f)$ on bodies `wrench_bodies`, each in its
      body's frame (torque about the body's origin), `(m, k, 6)`: `ExternalWrench`es.
    - `wrench_bodies`: the bodies the wrenches act on (static; `None` for the section frame).
    - `interpolation`: `"cubic"` (Hermite, through the samples, default) or `"linear"`
      (static). Between samples the inputs are this interpolation, so sample them as
      finely as the motion needs.
    """

    ts: Float[Array, " m"]
    joint_forces: Float[Array, "m d"] | None = None
    wrenches: Float[Array, "m k 6"] | None = None
    wrench_bodies: tuple[int | None, ...] = eqx.field(static=True, default=())
    interpolation: str = eqx.field(static=True, default="cubic")

    def __check_init__(self):
        if self.interpolation not in ("cubic", "linear"):
            raise ValueError("`Inputs.interpolation` must be 'cubic' or 'linear'.")
        if (self.wrenches is None) != (not self.wrench_bodies):
            raise ValueError("give `wrenches` and the bodies `wrench_bodies` they act on together.")

    def effects(self) -> list[AbstractEffect]:
        """The inputs as effects of a scene."""
        effects: list[AbstractEffect] = []
        if self.joint_forces is not None:
            path = _interpolate(self.ts, self.joint_forces, self.interpolation)
            effects.append(ShapeForce(_JointForce(path)))
        for k, body in enumerate(self.wrench_bodies):
            assert self.wrenches is not None
            path = _interpolate(self.ts, self.wrenches[:, k], self.interpolation)
            effects.append(ExternalWrench(_BodyWrench(path), body))
        return effects
