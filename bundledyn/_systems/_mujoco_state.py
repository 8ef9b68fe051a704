r"""MuJoCo's `qpos`, `qvel` to and from bundledyn's `State`, for every joint kind.

Pure JAX (no `mujoco` import): `jax.jit`, `jax.grad` and `jax.vmap` (over a batch of
states) work through both converters. Each is compiled whole (`equinox.filter_jit`), so
that a call outside `jit` (converting recorded states one by one) runs one program, not
one per operation.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.core import Tracer

from .. import lie
from .._state import State
from ._constrained import ConstrainedSystem
from ._multibody import AbstractMultibody

__all__ = ["state_from_mujoco", "state_to_mujoco"]


def _compiled_with_a_layout_flag(function):
    """`function` compiled whole (`equinox.filter_jit`), its `free_root` read as a Python
    bool first: `filter_jit` traces a NumPy bool (an array to it), and a traced flag cannot
    choose the layout."""
    compiled = eqx.filter_jit(function)

    @functools.wraps(function)
    def call(*args, free_root=True, **kwargs):
        if isinstance(free_root, Tracer) or np.ndim(free_root) != 0:
            raise TypeError(
                "`free_root` chooses the layout of qpos and qvel: give True or False (a "
                f"Python or NumPy bool), not {type(free_root).__name__} {free_root!r}."
            )
        return compiled(*args, free_root=bool(free_root), **kwargs)

    return call


def _layout(system: AbstractMultibody, free_root):
    """Static index tables between bundledyn's q and MuJoCo's qpos/qvel.

    Screw nodes (hinge/slide) take 1 qpos and 1 qvel entry, ball nodes 4 qpos (a
    quaternion) and 3 qvel entries, in node order, which is the order of q.
    """
    t = system.tables
    pos, vel = (7, 6) if free_root else (0, 0)
    screw_q, screw_pos, screw_vel, ball_q, ball_pos, ball_vel = [], [], [], [], [], []
    for kind, start in zip(t.kinds, t.q_start, strict=True):
        if kind == "screw":
            screw_q.append(start)
            screw_pos.append(pos)
            screw_vel.append(vel)
            pos, vel = pos + 1, vel + 1
        elif kind == "ball":
            ball_q.append(start + np.arange(3))
            ball_pos.append(pos + np.arange(4))
            ball_vel.append(vel + np.arange(3))
            pos, vel = pos + 4, vel + 3
    as_int = lambda x, shape: np.asarray(x, dtype=int).reshape(shape)
    return dict(
        screw_q=as_int(screw_q, (-1,)),
        screw_pos=as_int(screw_pos, (-1,)),
        screw_vel=as_int(screw_vel, (-1,)),
        ball_q=as_int(ball_q, (-1, 3)),
        ball_pos=as_int(ball_pos, (-1, 4)),
        ball_vel=as_int(ball_vel, (-1, 3)),
        nq=pos,
        nv=vel,
    )


def _check_length(name, x, n, free_root):
    if x.shape != (n,):
        free = " (7 free-joint entries first)" if free_root else " (no free-joint part)"
        raise ValueError(
            f"`{name}` must have shape ({n},){free} for this system with "
            f"free_root={free_root}, got {x.shape}; use jax.vmap for batches."
        )


def _screw_offsets(qpos0, lay, free_root, dtype):
    if qpos0 is None:
        return jnp.zeros(lay["screw_pos"].shape, dtype)
    qpos0 = jnp.asarray(qpos0, dtype)
    _check_length("qpos0", qpos0, lay["nq"], free_root)
    return qpos0[lay["screw_pos"]]


@_compiled_with_a_layout_flag
def state_from_mujoco(
    system: AbstractMultibody | ConstrainedSystem,
    qpos,
    qvel,
    *,
    qpos0=None,
    free_root=True,
    root_pose=None,
) -> State:
    r"""bundledyn's `State` $(g, q, \xi, \dot q)$ from MuJoCo's `qpos`, `qvel`.

    Conventions (architecture §2): $g$ is the pose of the section frame (the root body's frame
    for an imported model), $\xi = g^{-1}\dot g = (\omega, v)$ its body velocity. The free
    joint's `qpos` is (position, quaternion $w$ first) and its `qvel` is (linear velocity
    of the body origin in **world** axes, angular velocity in **body** axes), so
    $\xi = (\omega_{body}, R^T v_{world})$. The remaining coordinates follow MuJoCo's joint
    order: a hinge or slide has $q =$ `qpos - qpos0` and $\dot q =$ `qvel`; a ball joint
    has the rotation vector $\varphi$ of its quaternion ($\exp\tilde\varphi = R(\text{quat})$,
    $|\varphi| \le \pi$) and $\dot\varphi = \operatorname{dexp}^{-1}(\varphi)\,\omega$, $\omega$
    its `qvel` (the child's angular velocity relative to its parent, in the child's axes).
    With the section at another body than the root, $g = g_0 r_0^{-1}$ and
    $\xi = \operatorname{Ad}_{r_0}\nu_0 - Z_0\dot q$ from the root's pose $g_0$ and body
    velocity $\nu_0$ (`AbstractMultibody.root_in_section`).

    **Arguments:**

    - `system`: a tree imported by `Multibody.from_mjcf` or `from_urdf`, any section body;
      or an imported model with joint couplings (`ConstrainedSystem`), whose state holds
      the free coordinates (read off `qpos`, `qvel`; MuJoCo keeps the couplings only
      approximately, bundledyn's state exactly).
    - `qpos`, `qvel`: MuJoCo's generalized positions and velocities, shapes `(nq,)`, `(nv,)`.
    - `qpos0`: MuJoCo's `model.qpos0` (same layout as `qpos`), for joints with a non-zero
      `ref`; default: no offsets.
    - `free_root`: whether `qpos`/`qvel` start with the root's free joint (7/6 entries).
      For a root without a free joint, MuJoCo welds it to the world: then the root's pose
      is `root_pose` and its body velocity is zero.
    - `root_pose`: the root's 4×4 pose when `free_root=False` (MuJoCo's `xpos`/`xmat` of
      the root body); default identity.

    **Returns:**

    The `State`.
    """
    if isinstance(system, ConstrainedSystem):
        full = state_from_mujoco(
            _tree(system), qpos, qvel, qpos0=qpos0, free_root=free_root, root_pose=root_pose
        )
        free = system.constraints.free_coordinates
        return State(full.g, free(full.q), full.xi, free(full.qdot))
    qpos = jnp.asarray(qpos)
    qvel = jnp.asarray(qvel)
    dtype = jnp.result_type(qpos.dtype, qvel.dtype, float)
    qpos, qvel = qpos.astype(dtype), qvel.astype(dtype)
    lay = _layout(system, free_root)
    _check_length("qpos", qpos, lay["nq"], free_root)
    _check_length("qvel", qvel, lay["nv"], free_root)

    if free_root:
        R = lie.rotation_from_quaternion(qpos[3:7])
        g_root = lie.se3_from_rotation_translation(R, qpos[0:3])
        nu_root = jnp.concatenate([qvel[3:6], R.T @ qvel[0:3]])
    else:
        g_root = jnp.eye(4, dtype=dtype) if root_pose is None else jnp.asarray(root_pose, dtype)
        nu_root = jnp.zeros(6, dtype)

    offsets = _screw_offsets(qpos0, lay, free_root, dtype)
    phi = lie.rotation_vector_from_quaternion(qpos[lay["ball_pos"]])
    phidot = jnp.einsum("kij,kj->ki", lie.so3_dexp_inv(phi), qvel[lay["ball_vel"]])
    d = system.shape_dim
    q = jnp.zeros(d, dtype).at[lay["screw_q"]].set(qpos[lay["screw_pos"]] - offsets)
    q = q.at[lay["ball_q"]].set(phi)
    qdot = jnp.zeros(d, dtype).at[lay["screw_q"]].set(qvel[lay["screw_vel"]])
    qdot = qdot.at[lay["ball_q"]].set(phidot)

    r0, Z0 = system.root_in_section(q)
    g = g_root @ lie.se3_inv(r0)
    xi = lie.Ad(r0) @ nu_root - Z0 @ qdot
    return State(g, q, xi, qdot)


@_compiled_with_a_layout_flag
def state_to_mujoco(
    system: AbstractMultibody | ConstrainedSystem, state: State, *, qpos0=None, free_root=True
):
    r"""MuJoCo's `qpos`, `qvel` from bundledyn's `State` $(g, q, \xi, \dot q)$.

    The inverse of `state_from_mujoco` (same conventions): the free joint gets the root's
    position and unit quaternion ($w \ge 0$) and (world linear, body angular) velocity; a
    hinge or slide gets `qpos = q + qpos0`; a ball joint the unit quaternion of
    $\exp(\tilde\varphi)$ and `qvel` $= \operatorname{dexp}(\varphi)\dot\varphi$.

    **Arguments:**

    - `system`: the imported tree, or an imported model with joint couplings
      (`ConstrainedSystem`: the coupled joints' `qpos`, `qvel` from its couplings);
      `state`: its `State`.
    - `qpos0`: MuJoCo's `model.qpos0` (same layout as `qpos`), for joints with a non-zero
      `ref`; default: no offsets.
    - `free_root`: whether to write the root's free joint (7/6 entries) first. With
      `free_root=False` the pose and velocity of the root are dropped (MuJoCo welds a root
      without a free joint to the world).

    **Returns:**

    `(qpos, qvel)`, shapes `(nq,)`, `(nv,)`.
    """
    if isinstance(system, ConstrainedSystem):
        q, qdot = jax.jvp(system.constraints, (state.q,), (state.qdot,))
        full = State(state.g, q, state.xi, qdot)
        return state_to_mujoco(_tree(system), full, qpos0=qpos0, free_root=free_root)
    g, q, xi, qdot = state.g, state.q, state.xi, state.qdot
    dtype = g.dtype
    d = system.shape_dim
    if q.shape != (d,):
        raise ValueError(
            f"`state.q` must have shape ({d},), got {q.shape}; use jax.vmap for batches."
        )
    lay = _layout(system, free_root)

    qpos = jnp.zeros(lay["nq"], dtype)
    qvel = jnp.zeros(lay["nv"], dtype)
    if free_root:
        r0, Z0 = system.root_in_section(q)
        g_root = g @ r0
        nu_root = lie.Ad(lie.se3_inv(r0)) @ (xi + Z0 @ qdot)
        R = g_root[:3, :3]
        qpos = qpos.at[0:3].set(g_root[:3, 3]).at[3:7].set(lie.quaternion_from_rotation(R))
        qvel = qvel.at[0:3].set(R @ nu_root[3:6]).at[3:6].set(nu_root[0:3])

    offsets = _screw_offsets(qpos0, lay, free_root, dtype)
    qpos = qpos.at[lay["screw_pos"]].set(q[lay["screw_q"]] + offsets)
    qvel = qvel.at[lay["screw_vel"]].set(qdot[lay["screw_q"]])
    phi = q[lay["ball_q"]]
    omega = jnp.einsum("kij,kj->ki", lie.so3_dexp(phi), qdot[lay["ball_q"]])
    qpos = qpos.at[lay["ball_pos"]].set(lie.quaternion_from_rotation_vector(phi))
    qvel = qvel.at[lay["ball_vel"]].set(omega)
    return qpos, qvel


def _tree(system: ConstrainedSystem) -> AbstractMultibody:
    """The imported tree of a model with joint couplings."""
    if not isinstance(system.system, AbstractMultibody):
        raise ValueError(
            "MuJoCo's qpos and qvel describe an imported tree; this `ConstrainedSystem` "
            f"couples the coordinates of a {type(system.system).__name__}."
        )
    return system.system
