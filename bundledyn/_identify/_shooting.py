r"""Output error by multiple shooting: weighted residuals of windows and their exact Jacobian.

The horizon's samples are cut into $K$ windows of $M$ sample intervals. Window $k$ starts
at its first sample from a state $s_k$ and is integrated with the scene at the parameters
$\theta$ (`RKMK87`, fixed steps onto the sample times); its residuals are the measured
channels minus their predictions, each divided by its noise level. With fitted window
states (multiple shooting) the decision vector is $z = (\theta, s_1, \dots, s_K)$ and each
window also has continuity residuals, its predicted end state minus $s_{k+1}$, weighted far
above the data so that the fitted motion is one trajectory; with measured window states
only $\theta$ is fitted. $K = 1$ is single shooting.

A window state is $s = (\delta, q, \xi, \dot q)$ with the pose $\bar g\exp\hat\delta$ about a
reference pose $\bar g$ (the measured pose, or a nominal simulation's). The Jacobian is
exact, by forward mode (`diffrax.ForwardMode`) over $(\theta, s_k)$ window by window: the
windows only couple through the continuity rows, so the Jacobian is block sparse and each
window carries only its own tangents.
"""

import functools

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import lie
from .._batches import DeviceBatch, vmap_over_devices
from .._modes import AbstractWindowChart
from .._scene import Scene
from .._solver._rkmk import RKMK87
from .._state import State
from .._systems._ball_chart import ball_columns, shape_difference, shape_velocity_difference
from .._systems._multibody import AbstractMultibody
from .._term import SceneTerm
from ._data import Level, Measurements, Noise, level
from ._parameters import Parameters

__all__ = ["Windows", "ShootingProblem"]


class Windows(eqx.Module):
    """How the horizon is cut into shooting windows.

    **Arguments:**

    - `count`: the number of windows $K$ (static; 1 is single shooting).
    - `fit_states`: whether the windows' initial states are fitted with continuity
      between windows (multiple shooting, the default), or held at the measured states
      (static; needs the pose, twist, shape and shape velocity measured).
    - `substeps`: `RKMK87` steps per sample interval (static).
    - `continuity`: the continuity residuals' standard deviation as a fraction of the
      channels' noise levels; small, so that the windows join into one motion.
    """

    count: int = eqx.field(static=True, default=1)
    fit_states: bool = eqx.field(static=True, default=True)
    substeps: int = eqx.field(static=True, default=1)
    continuity: Level = eqx.field(default=1e-3, converter=level)

    def __check_init__(self):
        if self.count < 1 or self.substeps < 1:
            raise ValueError("`Windows.count` and `Windows.substeps` must be positive.")


def window_chart(scene: Scene) -> AbstractWindowChart:
    """The coordinates of the windows' initial states: the scene's mode's."""
    return scene.mode.window_chart(scene)


def _pose_residual(g_pred, g_meas, noise: Noise):
    rotation = lie.so3_log(g_meas[..., :3, :3].T @ g_pred[..., :3, :3]) / noise.rotation
    position = (g_pred[..., :3, 3] - g_meas[..., :3, 3]) / noise.position
    return jnp.concatenate([rotation, position])


def _grid(ts, count: int, substeps: int):
    """Per window, the sample index (clipped) and the validity of each of its M + 1
    samples, and the uniform times of its steps; M sample intervals per window."""
    ts = np.asarray(ts)
    n = ts.size
    M = -(-(n - 1) // count)
    dt = (ts[-1] - ts[0]) / (n - 1)
    if not np.allclose(np.diff(ts), dt, rtol=1e-6, atol=0.0):
        raise ValueError("shooting windows need uniformly sampled measurements.")
    index = np.arange(count)[:, None] * M + np.arange(M + 1)[None, :]
    last = np.zeros((count, M + 1), bool)
    last[-1, -1] = True
    measured = (index < n) & ((np.arange(M + 1) < M)[None, :] | last)
    steps = np.arange(count)[:, None] * M * substeps + np.arange(M * substeps + 1)[None, :]
    return np.minimum(index, n - 1), measured, ts[0] + dt * steps / substeps


@functools.lru_cache
def _spread(window_function, devices: tuple) -> DeviceBatch:
    """`window_function(problem, theta, *window arrays)` batched over the windows and spread
    over `devices` (`vmap_over_devices`): each device solves its share of the windows in
    its own loop, with no collective inside it; a window count the devices do not divide is
    padded. One per function and device set, so that a fit compiles it once."""
    mesh = jax.sharding.Mesh(np.array(devices), ("windows",))
    in_axes = (None, None, *(0,) * 7)
    return vmap_over_devices(window_function, in_axes=in_axes, mesh=mesh, keep_sharded=True)


def over_windows(window_function, problem, theta, batched):
    r"""`window_function` of every window, the windows spread over the local devices.

    The windows are independent until their Jacobians are assembled, so each device can
    solve a share of them. On a CPU, the devices are the ones
    `XLA_FLAGS=--xla_force_host_platform_device_count=N` creates (one per core to use),
    set before JAX starts.

    **Arguments:**

    - `window_function`: `(problem, theta, *one window's arrays) -> outputs`.
    - `problem`, `theta`: shared by every window.
    - `batched`: the windows' arrays, with the same leading size $K$.

    **Returns:**

    The outputs of every window, batched along their first axis.
    """
    return _spread(window_function, tuple(jax.local_devices()))(problem, theta, *batched)


def window_starts(ts, windows: Windows) -> np.ndarray:
    """The sample index at which each window starts, `(K,)`."""
    return _grid(ts, windows.count, windows.substeps)[0][:, 0]


class ShootingProblem(eqx.Module):
    r"""The weighted residuals of the windows and their exact, block-sparse Jacobian.

    **Arguments:**

    - `parameters`: the `Parameters` (the nominal scene and what is free).
    - `extra_effects`: effects added to the scene at every $\theta$ (the known inputs).
    - `measurements`: the `Measurements`.
    - `windows`: the `Windows`.
    - `references`: the windows' reference poses $\bar g$, `(K, 4, 4)`.
    """

    parameters: Parameters
    extra_effects: list
    measurements: Measurements
    windows: Windows
    references: jax.Array
    sample_index: jax.Array
    measured: jax.Array
    step_times: jax.Array

    def __init__(self, parameters, extra_effects, measurements, windows, references):
        self.parameters = parameters
        self.extra_effects = list(extra_effects)
        self.measurements = measurements
        self.windows = windows
        self.references = jnp.asarray(references)
        index, measured, times = _grid(measurements.ts, windows.count, windows.substeps)
        self.sample_index = jnp.asarray(index)
        self.measured = jnp.asarray(measured)
        self.step_times = jnp.asarray(times, dtype=float)

    def scene(self, theta) -> Scene:
        r"""The scene at $\theta$, with the known inputs."""
        scene = self.parameters.to_scene(theta)
        return eqx.tree_at(lambda s: s.effects, scene, [*scene.effects, *self.extra_effects])

    def _predicted_residuals(self, system, states, k_index, measured):
        """The weighted residuals of the measured channels at one window's samples."""
        m, noise = self.measurements, self.measurements.noise
        parts = []
        if m.pose is not None:
            parts.append(jax.vmap(_pose_residual, (0, 0, None))(states.g, m.pose[k_index], noise))
        # Ball joints are compared by rotation and angular velocity: a measured rotation
        # vector and a solved one can be the same turn in charts 2π apart.
        columns = ball_columns(system)
        if m.q is not None:
            q = jax.vmap(lambda a, b: shape_difference(columns, a, b))(states.q, m.q[k_index])
            parts.append(q / noise.q)
        if m.xi is not None:
            scale = jnp.array([noise.angular_velocity] * 3 + [noise.linear_velocity] * 3)
            parts.append((states.xi - m.xi[k_index]) / scale[None, :])
        if m.qdot is not None:
            measured_q = states.q if m.q is None else m.q[k_index]
            qdot = jax.vmap(functools.partial(shape_velocity_difference, columns))(
                states.q, states.qdot, measured_q, m.qdot[k_index]
            )
            parts.append(qdot / noise.qdot)
        if m.body_poses is not None:
            assert isinstance(system, AbstractMultibody)
            bodies = np.array(m.bodies, int)

            def body_residuals(state, measured_poses):
                poses = state.g @ system.body_poses(state.q)[bodies]
                return jax.vmap(_pose_residual, (0, 0, None))(poses, measured_poses, noise)

            parts.append(
                jax.vmap(body_residuals)(states, m.body_poses[k_index]).reshape(len(k_index), -1)
            )
        r = jnp.concatenate(parts, axis=1)
        return jnp.where(measured[:, None], r, 0.0).reshape(-1)

    @property
    def chart(self):
        """The window states' chart (`window_chart`)."""
        return window_chart(self.parameters.scene)

    def _continuity(self, end: State, s_next, g_ref_next):
        """Weighted continuity residual: the window's end state minus the next window's start."""
        start = self.chart.state(s_next, g_ref_next)
        return self.chart.difference(end, start, self.measurements.noise) / self.windows.continuity

    def window(self, theta, s, k_index, measured, times, g_ref):
        """One window: its weighted measurement residuals and its predicted end state."""
        scene = self.scene(theta)
        term = SceneTerm(scene)
        # diffrax directly, not `simulate`: the parameters and states here are physical by
        # construction, and a trial step that leaves the reasonable range must come back as
        # a large or non-finite residual (a rejected step), not as a run-time error.
        solution = diffrax.diffeqsolve(
            term,
            RKMK87(dense_output=False),
            times[0],
            times[-1],
            None,
            term.encode(times[0], self.chart.state(s, g_ref)),
            saveat=diffrax.SaveAt(t0=True, steps=True),
            stepsize_controller=diffrax.StepTo(ts=times),
            adjoint=diffrax.ForwardMode(),
            max_steps=times.shape[0] - 1,
        )
        sub = self.windows.substeps
        assert solution.ts is not None and solution.ys is not None  # saved at every step
        samples = jax.tree.map(lambda x: x[::sub], solution.ys)
        states = jax.vmap(term.decode)(solution.ts[::sub], samples)
        residuals = self._predicted_residuals(scene.system, states, k_index, measured)
        end = jax.tree.map(lambda x: x[-1], states)
        return residuals, end

    def _batched(self, S, S_next, refs, refs_next):
        """The windows' arguments, batched along their first axis."""
        return (S, S_next, self.sample_index, self.measured, self.step_times, refs, refs_next)

    def split(self, z):
        r"""$(\theta, S)$ of a decision vector: the parameters and the `(K, n_s)` window
        states (empty without fitted states)."""
        P = self.parameters.size
        return z[:P], z[P:].reshape(-1, self.chart.size)

    def _windows(self, z, window_states):
        """The windows' states, their successors' and the references, batched over windows."""
        theta, fitted = self.split(z)
        S = fitted if self.windows.fit_states else window_states
        refs = self.references
        return theta, S, jnp.roll(S, -1, axis=0), refs, jnp.roll(refs, -1, axis=0)

    def residuals(self, z, window_states):
        r"""The weighted data residuals and continuity defects at $z$ (no Jacobian): what a
        trial step is judged by.

        **Arguments:** as `residuals_and_jacobian`.

        **Returns:**

        `(r, c)`.
        """
        theta, S, S_next, refs, refs_next = self._windows(z, window_states)
        batched = self._batched(S, S_next, refs, refs_next)
        r, c = over_windows(_window_residuals, self, theta, batched)
        c = c[:-1].reshape(-1) if self.windows.fit_states else jnp.zeros((0,), r.dtype)
        return r.reshape(-1), c

    def residuals_and_jacobian(self, z, window_states):
        r"""The weighted data residuals and continuity defects at $z$, with their Jacobians.

        **Arguments:**

        - `z`: the decision vector ($\theta$, then the window states if they are fitted).
        - `window_states`: the window states $s_k$, `(K, n_s)`, used where they are not
          fitted (ignored otherwise).

        **Returns:**

        `(r, J, c, C)`: the data residuals `(R,)` and $\partial r/\partial z$; the
        continuity defects of windows $1..K-1$, `((K-1) n_s,)`, and $\partial c/\partial z$
        (empty without fitted states).
        """
        fit = self.windows.fit_states
        theta, S, S_next, refs, refs_next = self._windows(z, window_states)
        K, P, n_s = S.shape[0], theta.shape[0], S.shape[1]
        batched = self._batched(S, S_next, refs, refs_next)
        r, dr, c, dc, dc_next = over_windows(_window_jacobians, self, theta, batched)
        rows = r.shape[1]
        if not fit:
            empty = jnp.zeros((0,), r.dtype)
            return r.reshape(-1), dr.reshape(K * rows, P), empty, jnp.zeros((0, P), r.dtype)
        eye = jnp.eye(K, dtype=r.dtype)
        J_states = jnp.einsum("krs,kl->krls", dr[:, :, P:], eye).reshape(K * rows, K * n_s)
        J = jnp.concatenate([dr[:, :, :P].reshape(K * rows, P), J_states], axis=1)
        own = jnp.einsum("kcs,kl->kcls", dc[:, :, P:], eye)
        following = jnp.einsum("kcs,kl->kcls", dc_next, jnp.eye(K, k=1, dtype=r.dtype))
        C_states = (own + following)[:-1].reshape((K - 1) * n_s, K * n_s)
        C = jnp.concatenate([dc[:-1, :, :P].reshape((K - 1) * n_s, P), C_states], axis=1)
        return r.reshape(-1), J, c[:-1].reshape(-1), C


def _window_residuals(problem, theta, s, s_next, k_idx, meas, ts, g_ref, g_ref_next):
    """One window's weighted residuals and continuity defect."""
    r, end = problem.window(theta, s, k_idx, meas, ts, g_ref)
    return r, problem._continuity(end, s_next, g_ref_next)


def _window_jacobians(problem, theta, s, s_next, k_idx, meas, ts, g_ref, g_ref_next):
    """One window's residuals and continuity defect with their derivatives in
    $(\theta, s_k)$ (forward mode, one tangent per direction) and in $s_{k+1}$."""
    fit, P = problem.windows.fit_states, theta.shape[0]

    def outputs(x):
        th, s_ = (x[:P], x[P:]) if fit else (x, s)
        r, end = problem.window(th, s_, k_idx, meas, ts, g_ref)
        return r, problem._continuity(end, s_next, g_ref_next), end

    x0 = jnp.concatenate([theta, s]) if fit else theta
    basis = jnp.eye(x0.shape[0], dtype=x0.dtype)
    (r, c, end), (dr, dc, _) = jax.vmap(
        lambda v: jax.jvp(outputs, (x0,), (v,)), out_axes=((None,) * 3, (1, 1, 0))
    )(basis)
    dc_next = jax.jacfwd(lambda sn: problem._continuity(end, sn, g_ref_next))(s_next)
    return r, dr, c, dc, dc_next
