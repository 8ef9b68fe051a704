"""Trees of rigid bodies with a floating base, vectorized over bodies."""

import copy
import functools
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .. import lie
from .._linalg import einsum, matmul, take
from ._base import AbstractSystem
from ._joints import AbstractJoint
from ._metric_jet import AbstractMetricJet
from ._rigid_body import RigidBody, spatial_inertia
from ._validation import check_shape, concrete


class Link(eqx.Module):
    """A body attached to its parent by a joint.

    **Arguments:**

    - `body`: the `RigidBody` (its frame is the child frame of the joint).
    - `joint`: a joint (`Revolute`, `Prismatic`, `Universal`, `Spherical`, `Fixed`, `Composite`).
    - `parent`: index of the parent body; 0 is the floating base, $i \\ge 1$ is `links[i-1]`.
      Parents come before children.
    - `placement`: 4×4 pose of the child frame in the parent frame when the joint is at
      zero (MuJoCo's body `pos`/`quat`). Default: identity.
    """

    body: RigidBody
    joint: AbstractJoint
    parent: int = eqx.field(static=True)
    placement: Float[Array, "4 4"]

    def __init__(self, body, joint, parent, placement=None):
        self.body = body
        self.joint = joint
        self.parent = int(parent)
        self.placement = jnp.eye(4) if placement is None else jnp.asarray(placement, dtype=float)

    def __check_init__(self):
        if not isinstance(self.body, RigidBody):
            raise ValueError(f"`Link.body` must be a RigidBody, got {type(self.body).__name__}.")
        if not isinstance(self.joint, AbstractJoint):
            raise ValueError(
                f"unknown joint type {type(self.joint).__name__!r} in `Link.joint`; use "
                "Revolute, Prismatic, Universal, Spherical, Fixed or Composite."
            )
        check_shape("Link.placement", self.placement, (4, 4))
        T = concrete(self.placement)
        if T is not None:
            R = T[:3, :3]
            if (
                not np.allclose(R.T @ R, np.eye(3), atol=1e-8)
                or np.linalg.det(R) <= 0
                or not np.allclose(T[3], [0, 0, 0, 1], atol=1e-12)
            ):
                raise ValueError(f"`Link.placement` must be a rigid transform (SE(3)), got\n{T}.")


class _Tree(NamedTuple):
    """Hashable static tables of the tree (part of the jit cache key)."""

    kinds: tuple[str, ...]
    factor_index: tuple[int, ...]
    q_start: tuple[int, ...]
    node_body: tuple[int, ...]
    node_parent: tuple[int, ...]
    first: tuple[bool, ...]
    body_last: tuple[int, ...]
    path_mask: tuple[tuple[int, ...], ...]
    shape_dim: int


def _tree_tables(links, n_bodies):
    """Static index tables of the tree of joint factors ("nodes").

    Each body owns one node per elementary joint factor (one node if it has none); a
    node's parent is the previous node of its body or the last node of the parent body.
    """
    kinds, factor_index, q_start, node_body, node_parent, first = [], [], [], [], [], []
    screws, anchors = [], []
    body_last = [0]
    kinds.append("fixed"), factor_index.append(-1), q_start.append(0)
    node_body.append(0), node_parent.append(-1), first.append(False)
    qi = 0
    for i, link in enumerate(links, start=1):
        factors = link.joint.factors() or (("fixed", None),)
        prev = body_last[link.parent]
        for j, (kind, value) in enumerate(factors):
            kinds.append(kind)
            node_body.append(i)
            node_parent.append(prev)
            first.append(j == 0)
            q_start.append(qi)
            if kind == "screw":
                factor_index.append(len(screws)), screws.append(value)
                qi += 1
            elif kind == "ball":
                factor_index.append(len(anchors)), anchors.append(value)
                qi += 3
            else:
                factor_index.append(-1)
            prev = len(kinds) - 1
        body_last.append(prev)
    shape_dim = qi
    n_nodes = len(kinds)
    # Shape columns of each node and, per body, which columns move it (root-to-body path).
    node_columns = []
    for k in range(n_nodes):
        width = {"screw": 1, "ball": 3}.get(kinds[k], 0)
        node_columns.append(list(range(q_start[k], q_start[k] + width)))
    path_mask = np.zeros((n_bodies, shape_dim))
    for i in range(n_bodies):
        k = body_last[i]
        while k >= 0:
            path_mask[i, node_columns[k]] = 1.0
            k = node_parent[k]
    tree = _Tree(
        kinds=tuple(kinds),
        factor_index=tuple(factor_index),
        q_start=tuple(q_start),
        node_body=tuple(node_body),
        node_parent=tuple(node_parent),
        first=tuple(first),
        body_last=tuple(body_last),
        path_mask=tuple(tuple(int(v) for v in row) for row in path_mask),
        shape_dim=shape_dim,
    )
    return tree, screws, anchors


class Multibody(AbstractSystem):
    """A tree of rigid bodies with a floating base (seed 004, §4, systems of rigid bodies).

    The section frame is the frame of body `section` (the floating base, body 0, by
    default); shape coordinates $q$ are the joint coordinates in link order (each joint's
    factors in order). The metric is
    $G = \\sum_a \\hat J_a^T \\operatorname{Ad}_{r_a^{-1}}^T M_a \\operatorname{Ad}_{r_a^{-1}} \\hat J_a$
    with $\\hat J_a = [1 \\mid Z \\odot \\text{path}_a]$, $Z_j = \\operatorname{Ad}_{r_j} S_j$ the
    joint screws in the section frame (DESIGN §2), computed for all bodies at once.

    The joint screws `screw_axes` are unit screws (a rotation axis $|\\omega| = 1$, a
    translation $\\omega = 0$), and derivatives with respect to them are taken along unit
    screws: the axis turns and the moment $v$ moves freely, but $|\\omega|$ stays 1 and a
    translation's $\\omega$ stays 0, where the kinematics' Rodrigues formula holds.

    **Arguments:**

    - `base`: the floating base `RigidBody` (body 0).
    - `links`: a sequence of `Link`, body $i$ is `links[i-1]`.
    - `section`: the body whose frame is the section frame $r(q)$ (static; default 0).
    - `names`: optional body names (static), e.g. from MJCF.
    """

    mass: Float[Array, " n"]
    com: Float[Array, "n 3"]
    inertia: Float[Array, "n 3 3"]
    placement: Float[Array, "n 4 4"]
    screw_axes: Float[Array, "m 6"]
    ball_anchors: Float[Array, "k 3"]
    parents: tuple[int, ...] = eqx.field(static=True)
    joint_types: tuple[str, ...] = eqx.field(static=True)
    section: int = eqx.field(static=True)
    names: tuple[str, ...] = eqx.field(static=True)
    _tables: _Tree = eqx.field(static=True, repr=False)

    def __init__(self, base, links, *, section=0, names=None):
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
        if not 0 <= section < n:
            raise ValueError(f"`section` must index a body in 0..{n - 1}, got {section}.")
        tables, screws, anchors = _tree_tables(links, n)
        self.mass = jnp.stack([b.mass for b in bodies])
        self.com = jnp.stack([b.com for b in bodies])
        self.inertia = jnp.stack([b.inertia for b in bodies])
        self.placement = jnp.stack([jnp.eye(4), *(link.placement for link in links)])
        self.screw_axes = jnp.stack(screws) if screws else jnp.zeros((0, 6))
        self.ball_anchors = jnp.stack(anchors) if anchors else jnp.zeros((0, 3))
        self.parents = (-1, *(link.parent for link in links))
        self.joint_types = ("free", *(type(link.joint).__name__.lower() for link in links))
        self.section = int(section)
        self.names = tuple(names) if names is not None else tuple(f"body{i}" for i in range(n))
        self._tables = tables
        if len(self.names) != n:
            raise ValueError(f"`names` must name all {n} bodies, got {len(self.names)}.")

    # Static tables are plain tuples so the module hashes as jit's static structure.
    @property
    def num_bodies(self) -> int:
        return len(self.parents)

    @property
    def shape_dim(self) -> int:
        return self._tables.shape_dim

    def bodies(self) -> tuple[RigidBody, ...]:
        """The bodies as `RigidBody` objects (base first)."""
        return tuple(
            RigidBody(self.mass[i], self.com[i], self.inertia[i]) for i in range(self.num_bodies)
        )

    def with_section(self, section: int) -> "Multibody":
        """The same tree with body `section`'s frame as the section frame (a gauge change).

        **Arguments:**

        - `section`: index of the body whose frame becomes the section frame $r(q)$.
        """
        if not 0 <= section < self.num_bodies:
            raise ValueError(f"`section` must index a body in 0..{self.num_bodies - 1}.")
        # `section` is static structure, which `eqx.tree_at` cannot replace.
        other = copy.copy(self)
        object.__setattr__(other, "section", int(section))
        return other

    def _node_transforms(self, q):
        """Each node's factor transform $F_k$ and body-frame motion columns."""
        t = self._tables
        kinds = np.array(t.kinds)
        q_start = np.array(t.q_start)
        screw_nodes = np.flatnonzero(kinds == "screw")
        ball_nodes = np.flatnonzero(kinds == "ball")
        theta = take(q, q_start[screw_nodes])
        F_screw = _unit_screw_exp(_unit_screws(self.screw_axes), theta)
        phi = take(q, q_start[ball_nodes][:, None] + np.arange(3))
        R = lie.so3_exp(phi)
        a = self.ball_anchors
        p = a - matmul(R, a[..., None])[..., 0]
        F_ball = _pose(R, p)
        Jr = lie.so3_dexp(phi)
        S_ball = jnp.concatenate([Jr, matmul(lie.hat(a), Jr)], axis=-2)
        # One `take` places the factors in node order; fixed nodes take the identity.
        order = np.full(len(kinds), len(screw_nodes) + len(ball_nodes))
        order[screw_nodes] = np.arange(len(screw_nodes))
        order[ball_nodes] = len(screw_nodes) + np.arange(len(ball_nodes))
        F = take(jnp.concatenate([F_screw, F_ball, jnp.eye(4, dtype=q.dtype)[None]]), order)
        return F, screw_nodes, ball_nodes, S_ball

    def _node_poses(self, q):
        """Poses of all nodes in the base frame, by pointer jumping over the tree.

        $\\lceil\\log_2 \\text{depth}\\rceil$ batched products instead of one per level keeps the
        compiled graph small for deep chains.
        """
        t = self._tables
        F, screw_nodes, ball_nodes, S_ball = self._node_transforms(q)
        n_nodes = len(t.kinds)
        first = np.array(t.first)
        node_body = np.array(t.node_body)
        placement_index = np.where(first, node_body, 0)  # placement[0] is the identity
        T = matmul(take(self.placement, placement_index), F)
        sentinel = n_nodes
        anc = np.array([a if a >= 0 else sentinel for a in t.node_parent] + [sentinel])
        eye = jnp.eye(4, dtype=T.dtype)[None]
        while np.any(anc[:n_nodes] != sentinel):
            T = matmul(take(jnp.concatenate([T, eye]), anc[:n_nodes]), T)
            anc = anc[anc]
        return T, screw_nodes, ball_nodes, S_ball

    def body_poses(self, q: Float[Array, " d"]) -> Float[Array, "n 4 4"]:
        """Forward kinematics: the pose $r_a(q)$ of every body in the section frame.

        **Arguments:**

        - `q`: shape coordinates, shape `(d,)`.

        **Returns:**

        The 4×4 poses, shape `(n, 4, 4)`, base first.
        """
        T = take(self._node_poses(q)[0], self._tables.body_last)
        return self._to_section(T)

    def _to_section(self, T):
        if self.section == 0:
            return T
        return matmul(lie.se3_inv(T[self.section]), T)

    def _shape_columns(self, T, screw_nodes, ball_nodes, S_ball):
        """$Z$: every joint column as a twist in the base frame, shape (6, d)."""
        Z_screw = einsum("kij,kj->ik", lie.Ad(take(T, screw_nodes)), _unit_screws(self.screw_axes))
        Z_ball = einsum("kij,kjl->ikl", lie.Ad(take(T, ball_nodes)), S_ball).reshape(6, -1)
        q_start = np.array(self._tables.q_start)
        columns = np.concatenate(
            [q_start[screw_nodes], (q_start[ball_nodes][:, None] + np.arange(3)).reshape(-1)]
        ).astype(int)
        # Every coordinate is one joint's column: a permutation, not a scatter.
        return take(jnp.concatenate([Z_screw, Z_ball], axis=1), np.argsort(columns), axis=1)

    def velocity_jacobians(self, q):
        """Body-velocity map of every body: $\\hat J_a$ with $\\nu_a^{\\text{sec}} = \\hat J_a[\\xi;\\dot q]$.

        **Returns:**

        A pair `(r, Jhat)`: poses $r_a$ in the section frame `(n, 4, 4)` and the maps from
        $(\\xi, \\dot q)$ to each body's velocity expressed in the section frame, `(n, 6, 6+d)`.
        The body twist is $\\nu_a = \\operatorname{Ad}_{r_a^{-1}} \\hat J_a [\\xi; \\dot q]$.
        """
        *_, r, Jhat = self._jacobian_parts(q)
        return r, Jhat

    def _jacobian_parts(self, q):
        """Node poses, ball nodes, joint columns $Z$, body poses $r_a$ and $\\hat J_a$."""
        T, screw_nodes, ball_nodes, S_ball = self._node_poses(q)
        T_body = take(T, self._tables.body_last)
        Z = self._shape_columns(T, screw_nodes, ball_nodes, S_ball)
        mask = _column_tables(self._tables)[0]
        if self.section != 0:
            # Velocities relative to the section body, seen in its frame.
            Z = matmul(lie.Ad(lie.se3_inv(T_body[self.section])), Z)
            mask = mask - mask[self.section]
        mask = jnp.asarray(mask, q.dtype)
        eye = jnp.broadcast_to(jnp.eye(6, dtype=q.dtype), (self.num_bodies, 6, 6))
        Jhat = jnp.concatenate([eye, Z[None] * mask[:, None, :]], axis=-1)
        return T, ball_nodes, Z, self._to_section(T_body), Jhat

    def _section_inertias(self, r):
        """$\\tilde M_a = \\operatorname{Ad}_{r_a^{-1}}^T M_a \\operatorname{Ad}_{r_a^{-1}}$: each body's inertia in the section frame.

        Formed directly as the spatial inertia about the section origin of mass $m_a$ at
        $R_a c_a + p_a$ with rotational inertia $R_a J_a R_a^T$ (no 6×6 products).
        """
        R, p = r[:, :3, :3], r[:, :3, 3]
        com = jnp.einsum("aij,aj->ai", R, self.com) + p
        return spatial_inertia(self.mass, com, einsum("aij,ajk,alk->ail", R, self.inertia, R))

    def metric(self, q):
        r, Jhat = self.velocity_jacobians(q)
        # Σ_a Ĵ_aᵀ M_a Ĵ_a as one matrix product over the stacked rows of all bodies.
        rows = Jhat.reshape(-1, Jhat.shape[-1])
        return rows.T @ (self._section_inertias(r) @ Jhat).reshape(rows.shape)

    def metric_jet(self, q):
        """The metric and its derivative contractions in closed form (screw theory, DESIGN §4).

        Moving joint $k$ moves every node below it by the twist $Z_k$ (base frame), so
        $\\partial Z_j/\\partial q_k = \\operatorname{ad}_{Z_k} Z_j$ for $j$ at or below $k$ (plus, for a
        ball joint's own columns, the derivative of its $\\operatorname{dexp}$), and a body's
        inertia in the base frame $\\tilde M_a = \\operatorname{Ad}_{r_a^{-1}}^T M_a
        \\operatorname{Ad}_{r_a^{-1}}$ changes by
        $-(\\operatorname{ad}_{Z_k}^T \\tilde M_a + \\tilde M_a \\operatorname{ad}_{Z_k})$ when $k$ is on
        its path. These are the $\\nabla$ terms of (2.6)–(2.7) (seed 004); see `_TreeMetricJet`
        for the contractions, which cost about as much as the metric itself. A section other
        than the base uses the autodiff default.

        **Arguments:**

        - `q`: shape coordinates, shape `(d,)`.

        **Returns:**

        An `AbstractMetricJet`.
        """
        if self.section != 0 or self.shape_dim == 0:
            return super().metric_jet(q)
        T, ball_nodes, Z, r, _ = self._jacobian_parts(q)
        inertias = self._section_inertias(r)
        path, at_or_above, strictly_above = (
            jnp.asarray(a, q.dtype) for a in _column_tables(self._tables)
        )
        G = _composite_metric(inertias, Z, path, at_or_above, strictly_above)
        ball_dZ = self._ball_column_derivative(q, T, ball_nodes) if len(ball_nodes) else None
        return _TreeMetricJet(G, Z, inertias, ball_dZ, path, at_or_above, strictly_above)

    def metric_and_derivative(self, q):
        """$G(q)$ and $\\partial G/\\partial q_k$ in closed form (see `metric_jet`)."""
        if self.section != 0 or self.shape_dim == 0:
            return super().metric_and_derivative(q)
        jet = self.metric_jet(q)
        return jet.metric, jet.derivative()

    def _ball_column_derivative(self, q, T, ball_nodes):
        """$\\operatorname{Ad}_{T} \\partial S_i/\\partial\\varphi_l$ of each ball joint's own columns."""
        cols = np.array(self._tables.q_start)[ball_nodes][:, None] + np.arange(3)
        phi = take(q, cols)

        def columns(p, a):
            Jr = lie.so3_dexp(p)
            return jnp.concatenate([Jr, matmul(lie.hat(a), Jr)], axis=-2)

        dS = jax.vmap(jax.jacfwd(columns))(phi, self.ball_anchors)  # (k, 6, i, l)
        values = jnp.einsum("kxy,kyil->kilx", lie.Ad(take(T, ball_nodes)), dS)
        # Placed by products with constant 0/1 tables, not a scatter-add (a loop on XLA's CPU).
        place = (cols[..., None] == np.arange(self.shape_dim)).astype(values.dtype)
        return jnp.einsum("klm,kin,kilx->mxn", place, place, values)

    @classmethod
    def from_mjcf(cls, source, **kwargs) -> "Multibody":
        """Build a tree from an MJCF file path or XML string with mujoco's own parser.

        See `bundledyn._systems._mujoco.multibody_from_mjcf` (needs the `mujoco` extra).
        """
        from ._mujoco import multibody_from_mjcf

        return multibody_from_mjcf(source, **kwargs)

    @classmethod
    def from_urdf(cls, path, **kwargs) -> "Multibody":
        """Build a tree from a URDF file with mujoco's own parser (needs the `mujoco` extra)."""
        from ._mujoco import multibody_from_urdf

        return multibody_from_urdf(path, **kwargs)


@functools.cache
def _column_tables(t: _Tree) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Static relations of shape columns: `path` (n, d), column j moves body a;
    `at_or_above` (d, d), [k, j] = 1 where k's node is at or above j's node;
    `strictly_above` (d, d), [j, k] = 1 where j's node is strictly above k's node."""
    width = {"screw": 1, "ball": 3}
    node_of_column = [n for n, kind in enumerate(t.kinds) for _ in range(width.get(kind, 0))]
    A = np.zeros((t.shape_dim, t.shape_dim))
    for j, node in enumerate(node_of_column):
        while node >= 0:
            A[[k for k, m in enumerate(node_of_column) if m == node], j] = 1.0
            node = t.node_parent[node]
    same_node = np.equal.outer(node_of_column, node_of_column)
    path = np.array(t.path_mask, dtype=float).reshape(len(t.path_mask), t.shape_dim)
    return path, A, A * ~same_node


def _composite_metric(inertias, Z, path, at_or_above, strictly_above):
    """$G$ from composite (subtree) inertias, as in the composite-rigid-body algorithm.

    With $I^c_l = \\sum_{a \\succeq l} \\tilde M_a$ the inertia of the bodies joint column $l$
    moves: $I_r = \\sum_a \\tilde M_a$, $B_l = I^c_l Z_l$ and, for $j$ at or above $l$,
    $M_{jl} = Z_j^T I^c_l Z_l$ (zero for columns on different branches). This equals
    $\\sum_a \\hat J_a^T \\tilde M_a \\hat J_a$ (`Multibody.metric`) at $O(nd + d^2)$ cost instead of
    $O(n d^2)$.
    """
    composite = jnp.einsum("al,aij->lij", path, inertias)
    B = jnp.einsum("lij,jl->il", composite, Z)
    C = matmul(Z.T, B)  # C[j, l] = Z_j · I^c_l Z_l
    M = at_or_above * C + (strictly_above * C).T
    top = jnp.concatenate([jnp.sum(inertias, axis=0), B], axis=1)
    return jnp.concatenate([top, jnp.concatenate([B.T, M], axis=1)], axis=0)


class _TreeMetricJet(AbstractMetricJet):
    """The metric jet of a tree of bodies (section at the base), contracted in closed form.

    With $V_a(x) = \\hat J_a x$ each body's twist (base frame) for a velocity $x = [\\xi; \\dot q]$,
    $N_k(x)$ the twist of joint $k$'s parent node and $\\Pi_k(x) = \\sum_{a \\succeq k} \\tilde M_a V_a(x)$
    the momentum of the subtree that joint $k$ moves,

    $$x^T \\partial_k G\\, y = -[Z_k, N_k(x)]\\cdot\\Pi_k(y) - [Z_k, N_k(y)]\\cdot\\Pi_k(x)$$

    (plus a ball joint's $\\operatorname{dexp}$ term), which follows from `Multibody.metric_jet`'s
    derivatives of $Z$ and $\\tilde M_a$ because all terms inside the subtree cancel. Every
    contraction works on per-body 6-vectors; no $(6+d)$-wide matrix per body is formed.
    """

    metric: Float[Array, "6+d 6+d"]
    Z: Float[Array, "6 d"]
    inertias: Float[Array, "n 6 6"]
    ball_dZ: Float[Array, "d 6 d"] | None
    path: Float[Array, "n d"]
    at_or_above: Float[Array, "d d"]
    strictly_above: Float[Array, "d d"]

    def _twists(self, Z, X):
        """$\\hat J_a x$ with the columns `Z`, for each row $x$ of `X`: shape (m, n, 6)."""
        return X[:, None, :6] + einsum("il,ml,al->mai", Z, X[:, 6:], self.path)

    def _subtree_sums(self, f):
        """$\\sum_{a \\succeq l} f_a$ for each column $l$ of per-body vectors `f` (m, n, 6): (m, d, 6)."""
        return jnp.einsum("al,mai->mli", self.path, f)

    def along(self, u):
        return self.along_applied(u, jnp.eye(self.metric.shape[0], dtype=self.metric.dtype))

    def along_applied(self, u, X):
        # Moving the joints by u moves body a by W_a and column j by ∂_u Z_j = [W_j, Z_j],
        # W_j the twist of the joints at or above j; then with V = Ĵx and p = M̃V,
        # (∂_u G)x = Σ_a Ĵ_aᵀ(ad*_{W_a} p_a + M̃_a δV_a) + [0; ∂_u Z_l · Π_l], where
        # δV_a = (∂_u Ĵ_a)x - [W_a, V_a] is the change of the body twist.
        Zu = self.Z * u
        dZ = lie.bracket(matmul(Zu, self.at_or_above).T, self.Z.T).T
        if self.ball_dZ is not None:
            dZ = dZ + einsum("k,kxj->xj", u, self.ball_dZ)
        W = einsum("il,al->ai", Zu, self.path)
        V = self._twists(self.Z, X)
        p = jnp.einsum("aij,maj->mai", self.inertias, V)
        dV = self._twists(dZ, jnp.concatenate([jnp.zeros_like(X[:, :6]), X[:, 6:]], 1))
        dV = dV - lie.bracket(W, V)
        f = lie.coad_action(W, p) + jnp.einsum("aij,maj->mai", self.inertias, dV)
        shape = jnp.einsum("il,mli->ml", self.Z, self._subtree_sums(f)) + jnp.einsum(
            "il,mli->ml", dZ, self._subtree_sums(p)
        )
        return jnp.concatenate([jnp.sum(f, axis=1), shape], axis=1)

    def forms(self, X):
        N = X[:, None, :6] + einsum("ij,mj,jk->mki", self.Z, X[:, 6:], self.strictly_above)
        V = self._twists(self.Z, X)
        Pi = self._subtree_sums(jnp.einsum("aij,maj->mai", self.inertias, V))  # (m, d, 6)
        ZN = lie.bracket(self.Z.T, N)  # [Z_k, N_k(x_i)]
        if self.ball_dZ is not None:
            ZN = ZN - jnp.einsum("kxj,mj->mkx", self.ball_dZ, X[:, 6:])
        half = -jnp.einsum("ikx,jkx->ijk", ZN, Pi)
        return half + jnp.swapaxes(half, 0, 1)


@jax.custom_jvp
def _unit_screws(S):
    """The joint screws, differentiated along unit screws only (`Multibody`'s docstring)."""
    return S


@_unit_screws.defjvp
def _unit_screws_jvp(primals, tangents):
    (S,), (dS,) = primals, tangents
    w, dw = S[..., :3], dS[..., :3]
    # |ω|² dω - ω (ω·dω): the tangent of |ω| = 1 at a rotation axis, zero at a translation's ω = 0.
    dw = jnp.sum(w * w, axis=-1, keepdims=True) * dw - w * jnp.sum(w * dw, axis=-1, keepdims=True)
    return S, jnp.concatenate([dw, dS[..., 3:]], axis=-1)


def _unit_screw_exp(S, theta):
    r"""$\exp(\theta\hat S)$ for screws whose axis $\omega$ is a unit vector or zero.

    Rodrigues' formula with $|\omega| \in \{0, 1\}$ has no singular point, so joint screws
    need none of the Taylor branches of the general `lie.se3_exp`:
    $R = 1 + \sin\theta\,\tilde\omega + (1-\cos\theta)\tilde\omega^2$,
    $p = (\theta + (1-\cos\theta)\tilde\omega + (\theta-\sin\theta)\tilde\omega^2)\,v$.
    """
    w_hat = lie.hat(S[..., :3])
    w_hat2 = matmul(w_hat, w_hat)
    s, c = jnp.sin(theta)[..., None, None], (1.0 - jnp.cos(theta))[..., None, None]
    eye = jnp.eye(3, dtype=S.dtype)
    R = eye + s * w_hat + c * w_hat2
    V = theta[..., None, None] * eye + c * w_hat + (theta[..., None, None] - s) * w_hat2
    return _pose(R, matmul(V, S[..., 3:, None])[..., 0])


def _pose(R, p):
    top = jnp.concatenate([R, p[..., None]], axis=-1)
    bottom = jnp.broadcast_to(jnp.array([0.0, 0.0, 0.0, 1.0], dtype=R.dtype), (*R.shape[:-2], 1, 4))
    return jnp.concatenate([top, bottom], axis=-2)
