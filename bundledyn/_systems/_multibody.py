r"""Trees of rigid bodies with a floating base, vectorized over bodies."""

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .. import lie
from .._lie._so3 import so3_dexp_derivative
from .._linalg import einsum, materialized, matmul, take
from .._validation import check_shape, concrete
from ._base import AbstractInertialSystem, autodiff_metric_jet
from ._link import Link
from ._mujoco_import import ModelParts, parts_from_mjcf, parts_from_urdf
from ._pseudo_inertia import inertial_from_pseudo_inertia, pseudo_inertia
from ._rigid_body import RigidBody, spatial_inertia
from ._screws import pose, unit_screw_exp, unit_screws
from ._tree import Tree, column_tables, tree_tables
from ._tree_metric import BallColumnDerivative, TreeMetricJet, composite_metric
from ._validation import checked_inertia, checked_mass


class AbstractMultibody(AbstractInertialSystem):
    r"""A tree of rigid bodies floating in space: what effects, pictures and identification
    read of a tree besides its metric.

    Body $a$ has mass $m_a$, centre of mass $c_a$ and rotational inertia $J_a$ about it in its
    own frame, and sits at the pose $r_a(q)$ in the section frame.
    """

    mass: eqx.AbstractVar[Float[Array, " n"]]
    com: eqx.AbstractVar[Float[Array, "n 3"]]
    inertia: eqx.AbstractVar[Float[Array, "n 3 3"]]
    names: eqx.AbstractVar[tuple[str, ...]]
    tables: eqx.AbstractVar[Tree]
    fixed_centres: ClassVar[bool] = False

    @property
    def num_bodies(self) -> int:
        """The number $n$ of bodies (static)."""
        return len(self.names)

    @abc.abstractmethod
    def body_poses(self, q: Float[Array, " d"]) -> Float[Array, "n 4 4"]:
        r"""Forward kinematics: the pose $r_a(q)$ of every body in the section frame.

        **Arguments:**

        - `q`: shape coordinates, shape `(d,)`.

        **Returns:**

        The 4×4 poses, shape `(n, 4, 4)`, base first.
        """

    @abc.abstractmethod
    def velocity_jacobians(
        self, q: Float[Array, " d"]
    ) -> tuple[Float[Array, "n 4 4"], Float[Array, "n 6 6+d"]]:
        r"""Body-velocity map of every body: $\hat J_a$ with $\nu_a^{\text{sec}} = \hat J_a[\xi;\dot q]$.

        **Arguments:**

        - `q`: shape coordinates, shape `(d,)`.

        **Returns:**

        A pair `(r, Jhat)`: poses $r_a$ in the section frame `(n, 4, 4)` and the maps from
        $(\xi, \dot q)$ to each body's velocity expressed in the section frame, `(n, 6, 6+d)`.
        The body twist is $\nu_a = \operatorname{Ad}_{r_a^{-1}} \hat J_a [\xi; \dot q]$.
        """

    @abc.abstractmethod
    def root_in_section(
        self, q: Float[Array, " d"]
    ) -> tuple[Float[Array, "4 4"], Float[Array, "6 d"]]:
        r"""The root body's pose $r_0$ in the section frame and the joint columns $Z_0$ of its
        velocity there: $\nu_0 = \operatorname{Ad}_{r_0^{-1}}(\xi + Z_0\dot q)$.

        **Arguments:**

        - `q`: shape coordinates, shape `(d,)`.

        **Returns:**

        `(r0, Z0)`, shapes `(4, 4)` and `(6, d)`.
        """

    def pseudo_inertias(self):
        return pseudo_inertia(self.mass, self.com, self.inertia)

    def bodies(self) -> tuple[RigidBody, ...]:
        """The bodies as `RigidBody` objects (base first)."""
        return tuple(
            RigidBody(self.mass[i], self.com[i], self.inertia[i]) for i in range(self.num_bodies)
        )


def _ball_twists(R, c, axes):
    r"""Rotations about each ball joint's anchor, as twists in the base frame.

    A ball joint's column for the body-frame axis $\omega$ is $S\omega = (\omega, a\times\omega)$;
    in the base frame $\operatorname{Ad}_T S\omega = (R\omega, c\times R\omega)$ with
    $c = p + Ra$ the anchor's position there, formed without the 6×6 $\operatorname{Ad}_T$.

    **Arguments:**

    - `R`, `c`: the joints' rotations `(k, 3, 3)` and anchors `(k, 3)` in the base frame
      (`Multibody._ball_frames`).
    - `axes`: body-frame rotation axes as columns, shape `(k, ..., 3, m)`.

    **Returns:**

    Shape `(k, ..., 6, m)`.
    """
    lead = (slice(None),) + (None,) * (axes.ndim - 3)
    w = matmul(R[lead], axes)
    v = jnp.cross(c[lead][..., None], w, axis=-2)
    return jnp.concatenate([w, v], axis=-2)


class Multibody(AbstractMultibody):
    r"""A tree of rigid bodies with a floating base (seed 004, §4, systems of rigid bodies).

    The section frame is the frame of the floating base, body 0 (`with_section` moves it
    to another body); shape coordinates $q$ are the joint coordinates in link order (each
    joint's factors in order). The metric is
    $G = \sum_a \hat J_a^T \operatorname{Ad}_{r_a^{-1}}^T M_a \operatorname{Ad}_{r_a^{-1}} \hat J_a$
    with $\hat J_a = [1 \mid Z \odot \text{path}_a]$, $Z_j = \operatorname{Ad}_{r_j} S_j$ the
    joint screws in the section frame (architecture §2), computed for all bodies at once, plus the
    rotor inertia of the joints' drives: $\tfrac12\sum_j a_j \dot q_j^2$ adds $\operatorname{diag}(0_6, a)$
    (MuJoCo's `armature`). It involves neither $g$ nor $\xi$, so the metric stays
    $SE(3)$-invariant and every geometric quantity follows from it.

    The joint screws `screw_axes` are unit screws (a rotation axis $|\omega| = 1$, a
    translation $\omega = 0$), and derivatives with respect to them are taken along unit
    screws: the axis turns and the moment $v$ moves freely, but $|\omega|$ stays 1 and a
    translation's $\omega$ stays 0, where the kinematics' Rodrigues formula holds.

    **Arguments:**

    - `base`: the floating base `RigidBody` (body 0).
    - `links`: a sequence of `Link`, body $i$ is `links[i-1]`.
    - `names`: optional body names (static), e.g. from MJCF.
    - `armature`: the rotor inertia $a_j \ge 0$ of each shape coordinate, shape `(d,)`
      (default zero); hinge and slide coordinates only.
    """

    mass: Float[Array, " n"]
    com: Float[Array, "n 3"]
    inertia: Float[Array, "n 3 3"]
    placement: Float[Array, "n 4 4"]
    screw_axes: Float[Array, "m 6"]
    ball_anchors: Float[Array, "k 3"]
    armature: Float[Array, " d"]
    parents: tuple[int, ...] = eqx.field(static=True)
    joint_types: tuple[str, ...] = eqx.field(static=True)
    names: tuple[str, ...] = eqx.field(static=True)
    tables: Tree = eqx.field(static=True, repr=False)

    def __init__(self, base, links, *, names=None, armature=None):
        links = tuple(links)
        for i, link in enumerate(links, start=1):
            if not isinstance(link, Link):
                raise ValueError(f"`links[{i - 1}]` must be a `Link`, got {type(link).__name__}.")
            if not 0 <= link.parent < i:
                raise ValueError(
                    f"`links[{i - 1}].parent` is {link.parent}; it must index an earlier body "
                    f"(0 for the base, 1..{i - 1} for earlier links)."
                )
        if not isinstance(base, RigidBody):
            raise ValueError(f"`base` must be a RigidBody, got {type(base).__name__}.")
        bodies = (base, *(link.body for link in links))
        n = len(bodies)
        tables, screws, anchors = tree_tables(links, n)
        self.mass = jnp.stack([b.mass for b in bodies])
        self.com = jnp.stack([b.com for b in bodies])
        self.inertia = jnp.stack([b.inertia for b in bodies])
        self.placement = jnp.stack([jnp.eye(4), *(link.placement for link in links)])
        self.screw_axes = jnp.stack(screws) if screws else jnp.zeros((0, 6))
        self.ball_anchors = jnp.stack(anchors) if anchors else jnp.zeros((0, 3))
        self.parents = (-1, *(link.parent for link in links))
        self.joint_types = ("free", *(type(link.joint).__name__.lower() for link in links))
        self.names = tuple(names) if names is not None else tuple(f"body{i}" for i in range(n))
        self.tables = tables
        if len(self.names) != n:
            raise ValueError(f"`names` must name all {n} bodies, got {len(self.names)}.")
        d = tables.shape_dim
        self.armature = jnp.zeros(d) if armature is None else jnp.asarray(armature, dtype=float)
        _check_armature(self.armature, tables)

    @property
    def shape_dim(self) -> int:
        return self.tables.shape_dim

    def with_section(self, section: int) -> AbstractMultibody:
        r"""The same tree with body `section`'s frame as the section frame (a gauge change).

        **Arguments:**

        - `section`: index of the body whose frame becomes the section frame $r(q)$.

        **Returns:**

        This tree itself for `section = 0`, otherwise a `Resectioned` tree.
        """
        return self if section == 0 else Resectioned(self, section)

    def _node_transforms(self, q):
        """Each node's factor transform $F_k$ and body-frame motion columns."""
        t = self.tables
        kinds = np.array(t.kinds)
        q_start = np.array(t.q_start)
        screw_nodes = np.flatnonzero(kinds == "screw")
        ball_nodes = np.flatnonzero(kinds == "ball")
        theta = take(q, q_start[screw_nodes])
        F_screw = unit_screw_exp(unit_screws(self.screw_axes), theta)
        phi = take(q, q_start[ball_nodes][:, None] + np.arange(3))
        R = lie.so3_exp(phi)
        a = self.ball_anchors
        p = a - matmul(R, a[..., None])[..., 0]
        F_ball = pose(R, p)
        Jr = lie.so3_dexp(phi)
        # One `take` places the factors in node order; fixed nodes take the identity.
        order = np.full(len(kinds), len(screw_nodes) + len(ball_nodes))
        order[screw_nodes] = np.arange(len(screw_nodes))
        order[ball_nodes] = len(screw_nodes) + np.arange(len(ball_nodes))
        F = take(jnp.concatenate([F_screw, F_ball, jnp.eye(4, dtype=q.dtype)[None]]), order)
        return F, screw_nodes, ball_nodes, Jr

    def _node_poses(self, q):
        r"""Poses of all nodes in the base frame, by pointer jumping over the tree.

        $\lceil\log_2 \text{depth}\rceil$ batched products instead of one per level keeps the
        compiled graph small for deep chains.
        """
        t = self.tables
        F, screw_nodes, ball_nodes, Jr = self._node_transforms(q)
        n_nodes = len(t.kinds)
        first = np.array(t.first)
        node_body = np.array(t.node_body)
        placement_index = np.where(first, node_body, 0)  # placement[0] is the identity
        T = matmul(take(self.placement, placement_index), F)
        sentinel = n_nodes
        anc = np.array([a if a >= 0 else sentinel for a in t.node_parent] + [sentinel])
        eye = jnp.eye(4, dtype=T.dtype)[None]
        while np.any(anc[:n_nodes] != sentinel):
            T = materialized(matmul(take(jnp.concatenate([T, eye]), anc[:n_nodes]), T))
            anc = anc[anc]
        return T, screw_nodes, ball_nodes, Jr

    def body_poses(self, q):
        return take(self._node_poses(q)[0], self.tables.body_last)

    def _ball_frames(self, T, ball_nodes):
        r"""Each ball joint's rotation $R$ and centre $c = p + Ra$ in the base frame, from
        the node poses `T` `(nodes, 4, 4)`: shapes `(k, 3, 3)` and `(k, 3)`."""
        T_ball = take(T, ball_nodes)
        R = T_ball[:, :3, :3]
        return R, T_ball[:, :3, 3] + matmul(R, self.ball_anchors[..., None])[..., 0]

    def _shape_columns(self, T, screw_nodes, ball_nodes, Jr):
        """$Z$: every joint column as a twist in the base frame, shape (6, d)."""
        Z_screw = einsum("kij,kj->ik", lie.Ad(take(T, screw_nodes)), unit_screws(self.screw_axes))
        Z_ball = jnp.moveaxis(_ball_twists(*self._ball_frames(T, ball_nodes), Jr), 0, 1)
        Z_ball = Z_ball.reshape(6, -1)
        q_start = np.array(self.tables.q_start)
        columns = np.concatenate(
            [q_start[screw_nodes], (q_start[ball_nodes][:, None] + np.arange(3)).reshape(-1)]
        ).astype(int)
        # Every coordinate is one joint's column: a permutation, not a scatter.
        return take(jnp.concatenate([Z_screw, Z_ball], axis=1), np.argsort(columns), axis=1)

    def joint_columns(self, q):
        r"""$Z(q)$: each shape coordinate's joint screw as a twist in the base frame, `(6, d)`.

        Moving coordinate $j$ alone moves every body below its joint with the twist $Z_j$.
        """
        return self._shape_columns(*self._node_poses(q))

    def velocity_jacobians(self, q):
        *_, r, Jhat = self._jacobian_parts(q)
        return r, Jhat

    def root_in_section(self, q):
        return jnp.eye(4, dtype=q.dtype), jnp.zeros((6, self.shape_dim), q.dtype)

    def _jacobian_parts(self, q):
        r"""Node poses, ball nodes, joint columns $Z$, body poses $r_a$ and $\hat J_a$."""
        T, screw_nodes, ball_nodes, Jr = self._node_poses(q)
        Z = self._shape_columns(T, screw_nodes, ball_nodes, Jr)
        mask = jnp.asarray(column_tables(self.tables)[0], q.dtype)
        eye = jnp.broadcast_to(jnp.eye(6, dtype=q.dtype), (self.num_bodies, 6, 6))
        Jhat = jnp.concatenate([eye, Z[None] * mask[:, None, :]], axis=-1)
        return T, ball_nodes, Z, take(T, self.tables.body_last), Jhat

    def _section_inertias(self, r):
        r"""$\tilde M_a = \operatorname{Ad}_{r_a^{-1}}^T M_a \operatorname{Ad}_{r_a^{-1}}$: each body's inertia in the section frame.

        Formed directly as the spatial inertia about the section origin of mass $m_a$ at
        $R_a c_a + p_a$ with rotational inertia $R_a J_a R_a^T$ (no 6×6 products).
        """
        R, p = r[:, :3, :3], r[:, :3, 3]
        com = jnp.einsum("aij,aj->ai", R, self.com) + p
        return spatial_inertia(self.mass, com, einsum("aij,ajk,alk->ail", R, self.inertia, R))

    def _rotor_inertia(self, dtype):
        r"""$\operatorname{diag}(0_6, a)$: the drives' rotor inertia in the metric (constant in $q$)."""
        return jnp.diag(jnp.concatenate([jnp.zeros(6, dtype), self.armature.astype(dtype)]))

    def metric(self, q):
        r, Jhat = self.velocity_jacobians(q)
        # Σ_a Ĵ_aᵀ M_a Ĵ_a as one matrix product over the stacked rows of all bodies.
        rows = Jhat.reshape(-1, Jhat.shape[-1])
        bodies = rows.T @ (self._section_inertias(r) @ Jhat).reshape(rows.shape)
        return bodies + self._rotor_inertia(q.dtype)

    def metric_jet(self, q):
        r"""The metric and its derivative contractions in closed form (screw theory, architecture §4.3).

        Moving joint $k$ moves every node below it by the twist $Z_k$ (base frame), so
        $\partial Z_j/\partial q_k = \operatorname{ad}_{Z_k} Z_j$ for $j$ at or below $k$ (plus, for a
        ball joint's own columns, the derivative of its $\operatorname{dexp}$), and a body's
        inertia in the base frame $\tilde M_a = \operatorname{Ad}_{r_a^{-1}}^T M_a
        \operatorname{Ad}_{r_a^{-1}}$ changes by
        $-(\operatorname{ad}_{Z_k}^T \tilde M_a + \tilde M_a \operatorname{ad}_{Z_k})$ when $k$ is on
        its path. These are the $\nabla$ terms of (2.6)–(2.7) (seed 004); see `TreeMetricJet`
        for the contractions, which cost about as much as the metric itself.

        **Arguments:**

        - `q`: shape coordinates, shape `(d,)`.

        **Returns:**

        An `AbstractMetricJet`.
        """
        T, ball_nodes, Z, r, _ = self._jacobian_parts(q)
        inertias = self._section_inertias(r)
        path, at_or_above, strictly_above = (
            jnp.asarray(a, q.dtype) for a in column_tables(self.tables)
        )
        G = composite_metric(inertias, Z, path, at_or_above, strictly_above)
        G = G + self._rotor_inertia(q.dtype)  # constant: no derivative terms
        ball_dZ = self._ball_column_derivative(q, T, ball_nodes) if len(ball_nodes) else None
        joints_at_or_above = jnp.asarray(column_tables(self.tables)[1].T, q.dtype)
        return TreeMetricJet(G, Z, inertias, ball_dZ, path, joints_at_or_above, strictly_above)

    def _ball_column_derivative(self, q, T, ball_nodes) -> BallColumnDerivative:
        r"""$\operatorname{Ad}_{T} \partial S_i/\partial\varphi_l$ of each ball joint's own columns,
        $S = [J_r; \hat a J_r]$ with $J_r = \operatorname{dexp}(\varphi)$ (`so3_dexp_derivative`),
        with what their next derivative needs (`BallColumnDerivative`)."""
        cols = np.array(self.tables.q_start)[ball_nodes][:, None] + np.arange(3)
        phi = take(q, cols)
        R, c = self._ball_frames(T, ball_nodes)
        values = jnp.swapaxes(_ball_twists(R, c, so3_dexp_derivative(phi)), -1, -2)
        columns = tuple(map(tuple, cols.tolist()))
        return BallColumnDerivative(values, phi, R, c, columns, self.shape_dim)

    def with_pseudo_inertias(self, P) -> "Multibody":
        m, c, J = inertial_from_pseudo_inertia(P)
        return eqx.tree_at(lambda b: (b.mass, b.com, b.inertia), self, (m, c, J))

    def checked(self) -> "Multibody":
        mass = checked_mass("Multibody.mass", self.mass)
        inertia = checked_inertia("Multibody.inertia", self.inertia)
        return eqx.tree_at(lambda b: (b.mass, b.inertia), self, (mass, inertia))

    @classmethod
    def from_parts(cls, parts: ModelParts, *, section=0) -> AbstractMultibody:
        """The tree of an imported model's parts (`ModelParts`), its section at body `section`:
        the tree alone, without the model's joint couplings (`parts.couplings`, which
        `bd.Scene.from_mjcf` and `bd.load_system` keep as a `ConstrainedSystem`)."""
        system = cls(parts.base, parts.links, names=parts.names, armature=parts.armature)
        if isinstance(section, str):
            if section not in parts.names:
                raise ValueError(
                    f"`section` names body {section!r}, which is not a body of the imported "
                    f"tree; its bodies are {list(parts.names)}."
                )
            section = parts.names.index(section)
        return system.with_section(section)

    @classmethod
    def from_mjcf(cls, source, *, section=0) -> AbstractMultibody:
        """Build a tree from an MJCF model with MuJoCo's own parser (the `mujoco` extra).

        The import is described in `bundledyn._systems._mujoco_import` (what is kept, what
        is ignored with a warning, what is refused with a `ValueError`).

        **Arguments:**

        - `source`: a path (`str` or `os.PathLike`) to an MJCF file, an MJCF XML string, or
          an already compiled `mujoco.MjModel`.
        - `section`: the body whose frame is the section frame, by index (0, the root, by
          default) or by MuJoCo body name.

        **Returns:**

        A `Multibody` whose base is the root body and whose links follow MuJoCo's body
        order (a `Resectioned` one for another section); `names` are the MuJoCo body names.
        Its states relate to MuJoCo's `qpos`/`qvel` through `state_from_mujoco` and
        `state_to_mujoco`.
        """
        return cls.from_parts(_uncoupled(parts_from_mjcf(source)), section=section)

    @classmethod
    def from_urdf(cls, path, *, section=0) -> AbstractMultibody:
        """Build a tree from a URDF file with MuJoCo's own URDF parser (the `mujoco` extra).

        The root link becomes the floating base (see `parts_from_urdf`).

        **Arguments:**

        - `path`: path to a `.urdf` file; `section`: as in `from_mjcf`.

        **Returns:**

        As `from_mjcf`.
        """
        return cls.from_parts(parts_from_urdf(path), section=section)


def _check_armature(armature, tables: Tree):
    """`ValueError` with the fix for a rotor inertia of the wrong shape, negative, or on a
    ball joint (whose coordinates are not its angular velocity); values only when concrete."""
    check_shape("armature", armature, (tables.shape_dim,))
    a = concrete(armature)
    if a is None:
        return
    if np.any(a < 0):
        raise ValueError(f"`armature` must be non-negative, got {a}.")
    kinds, starts = np.array(tables.kinds), np.array(tables.q_start)
    ball = (starts[kinds == "ball"][:, None] + np.arange(3)).reshape(-1).astype(int)
    if np.any(a[ball] != 0):
        raise ValueError(
            "`armature` on a ball joint's coordinates is not supported (they are exponential "
            "coordinates, not its angular velocity): set it to 0 there."
        )


class Resectioned(AbstractMultibody):
    r"""A `Multibody` whose section frame is the frame of another of its bodies: a gauge change.

    With $r_k(q)$ the pose of body $k$ in the base frame, the new section is $g_k = g\,r_k$
    and its body velocity $\xi_k = \operatorname{Ad}_{r_k^{-1}}(\xi + Z_k\dot q)$, $Z_k$ the joint
    columns on the path to body $k$. So $(\xi, \dot q) = L(\xi_k, \dot q)$ with
    $L = \begin{bmatrix}\operatorname{Ad}_{r_k} & -Z_k \\ 0 & 1\end{bmatrix}$ and the metric is
    $L^T G L$; the shape metric is unchanged and the curvature moves by
    $\operatorname{Ad}_{r_k^{-1}}$ (seed 004, §2). Its metric jet is by autodiff.

    **Arguments:**

    - `tree`: the `Multibody` (section at its base).
    - `section`: index of the body whose frame is the section frame (static).
    """

    tree: Multibody
    section: int = eqx.field(static=True)

    # Written out: the `__init__` a type checker derives asks for the abstract fields too,
    # which the properties below provide. equinox takes a property for an `AbstractVar`;
    # pyright takes an `AbstractVar` for a writable attribute, which a property is not (a
    # Module is frozen anyway): hence its `ignore`s.
    def __init__(self, tree: Multibody, section: int):
        self.tree = tree
        self.section = section

    def __check_init__(self):
        if not 0 <= self.section < self.tree.num_bodies:
            raise ValueError(
                f"`section` must index a body in 0..{self.tree.num_bodies - 1}, got {self.section}."
            )

    @property
    def mass(self):  # pyright: ignore[reportIncompatibleVariableOverride]
        return self.tree.mass

    @property
    def com(self):  # pyright: ignore[reportIncompatibleVariableOverride]
        return self.tree.com

    @property
    def inertia(self):  # pyright: ignore[reportIncompatibleVariableOverride]
        return self.tree.inertia

    @property
    def names(self):  # pyright: ignore[reportIncompatibleVariableOverride]
        return self.tree.names

    @property
    def tables(self):  # pyright: ignore[reportIncompatibleVariableOverride]
        return self.tree.tables

    @property
    def shape_dim(self) -> int:
        return self.tree.shape_dim

    def _change(self, q):
        """$r_k$ and the map $L$ from this section's velocities to the base section's."""
        r, Jhat = self.tree.velocity_jacobians(q)
        r_k = r[self.section]
        d = self.shape_dim
        top = jnp.concatenate([lie.Ad(r_k), -Jhat[self.section, :, 6:]], axis=1)
        bottom = jnp.concatenate([jnp.zeros((d, 6), q.dtype), jnp.eye(d, dtype=q.dtype)], axis=1)
        return r_k, jnp.concatenate([top, bottom])

    def body_poses(self, q):
        r_k, _ = self._change(q)
        return matmul(lie.se3_inv(r_k), self.tree.body_poses(q))

    def velocity_jacobians(self, q):
        r_k, L = self._change(q)
        r, Jhat = self.tree.velocity_jacobians(q)
        Ad_inv = lie.Ad(lie.se3_inv(r_k))
        return matmul(lie.se3_inv(r_k), r), jnp.einsum("ij,ajk,kl->ail", Ad_inv, Jhat, L)

    def root_in_section(self, q):
        r, Jhat = self.velocity_jacobians(q)
        return r[0], Jhat[0, :, 6:]

    def metric(self, q):
        _, L = self._change(q)
        return L.T @ self.tree.metric(q) @ L

    def metric_jet(self, q):
        return autodiff_metric_jet(self, q)

    def with_pseudo_inertias(self, P) -> "Resectioned":
        return Resectioned(self.tree.with_pseudo_inertias(P), self.section)

    def checked(self) -> "Resectioned":
        return Resectioned(self.tree.checked(), self.section)


def _uncoupled(parts: ModelParts) -> ModelParts:
    """`parts`, refused with a `ValueError` if the model couples joints: a tree alone would
    move without its couplings."""
    if parts.couplings:
        raise ValueError(
            f"the model couples joints ({len(parts.couplings)} <equality><joint>), which a "
            "Multibody alone does not keep: use `bd.Scene.from_mjcf` or `bd.load_system`, "
            "which give the tree with its couplings as a `ConstrainedSystem`."
        )
    return parts
