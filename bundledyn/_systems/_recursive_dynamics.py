r"""The accelerations of a tree of bodies by recursions over its levels (articulated bodies).

The same equations as the dense field of (2.6)–(2.7) (seed 004) and the reference form
(architecture §3), solved without forming the metric: every quantity is a twist, a
wrench or a $6\times6$ inertia of one body, all in the section frame (the base's, body 0),
so no transform is needed between a body and its parent. Body $a$ moves with
$V_a = \xi + W_a$, $W_a = \sum_{j \preceq a} Z_j\dot q_j$ the twist of the joint columns on
its path; its momentum $p_a = \tilde M_a V_a$ obeys Newton–Euler in the section frame,
$f_a = \tilde M_a\mathcal A_a + \operatorname{ad}^*_{V_a}p_a$ with
$\mathcal A_a = \dot V_a + [\xi, V_a]$ its acceleration (that of the world frame, in the
section's axes), because $\tilde M_a$ turns with the body at the rate $W_a$; summed over the
bodies this is the reference form's group equation, and $Z_j\cdot\sum_{a\succeq j} f_a +
a_j\ddot q_j = Q_{H,j}$ its shape rows ($a_j$ the rotor inertia).

The articulated-body algorithm solves them in $O(n)$ work: a pass from the leaves gathers
each subtree into an articulated inertia and bias, a pass from the root gives each joint's
accelerations. Bodies of one depth are processed together, so the passes are as many
steps as the tree is deep, each a few kernels on all the bodies of a level, and a joint's
coordinates (a hinge, a ball, a composite joint) are one block, padded to the widest of
its level. Path sums (the twists $W$) are by pointer jumping, as the node poses of
`Multibody`. Every index into the tree's orders is a gather: `_linalg.take`'s slices
would cost a kernel per run of consecutive rows.

The locked velocity's rate needs no shape acceleration: $I_rU = \sum_a p_a$ is the total
momentum, whose rate is $\operatorname{ad}^T_\xi I_rU + F_b$, so
$I_r\dot U = F_b - \operatorname{ad}^*_\xi I_rU - (\partial_{\dot q}I_r)U$, the group equation
(2.7) with its terms gathered.
"""

import functools
from typing import NamedTuple

import jax.lax as lax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .. import lie
from .._lie._so3 import so3_dexp_derivative
from .._linalg import einsum, materialized, matmul, spd_inverse_6x6, spd_solve, take
from ._multibody import Multibody
from ._tree import Tree

__all__ = [
    "NodeMotion",
    "TreeMotion",
    "at_bodies",
    "body_twist",
    "covers",
    "driven_accelerations",
    "floating_accelerations",
    "locked_rate",
    "metric_solve",
    "node_motion",
    "node_path_sums",
    "node_twists",
    "tree_motion",
    "uniform_field_twist",
]

_WIDTH = {"fixed": 0, "screw": 1, "ball": 3}


class _Levels(NamedTuple):
    r"""The bodies of a tree by depth, and where their joints' coordinates are (static).

    **Fields:**

    - `order`: the bodies $1..n-1$ level by level, each parent's children together and
      in its order, so that a level is a slice and a parent's children a run of it.
    - `bounds`: level $L \ge 1$ is `order[bounds[L-1]:bounds[L]]`.
    - `widths`: per level, the most coordinates of one of its joints.
    - `parents`: per level, its bodies' parents as a 0/1 matrix `(bodies, bodies of the
      level above)` (level 0 is the base alone): the pass from the root takes each body's
      parent's row through it, the pass from the leaves sums each body's children's
      through its transpose.
    - `columns`: each body's coordinates in `order`, `(n-1, widest)`, padded with $d$.
    - `solved`: each coordinate's position among the levels' padded blocks, flattened and
      joined.
    - `node_parents`: each node's parent node, the node count for the root.
    - `body_nodes`: each body's nodes, `(n, most)`, padded with the node count.
    """

    order: np.ndarray
    bounds: tuple[int, ...]
    widths: tuple[int, ...]
    parents: tuple[np.ndarray, ...]
    columns: np.ndarray
    solved: np.ndarray
    node_parents: np.ndarray
    body_nodes: np.ndarray


def _by_level(parents):
    """The bodies below the base level by level, children grouped by parent: a list of
    levels, the base's level first."""
    levels = [[0]]
    while True:
        below = [c for p in levels[-1] for c in range(1, len(parents)) if parents[c] == p]
        if not below:
            return levels
        levels.append(below)


def _padded(rows, fill):
    """Integer lists as one array, each row padded with `fill` to the longest."""
    width = max((len(r) for r in rows), default=0)
    return np.array([list(r) + [fill] * (width - len(r)) for r in rows], dtype=int).reshape(
        len(rows), width
    )


@functools.cache
def _levels(tables: Tree, parents: tuple[int, ...]) -> _Levels:
    """The `_Levels` of a tree with the node tables `tables` and body parents `parents`."""
    unknown = set(tables.kinds) - set(_WIDTH)
    if unknown:
        raise ValueError(
            f"the recursive accelerations cover hinges, slides, balls and welds, not joint "
            f"factors of kind {sorted(unknown)}: use the dense field."
        )
    d, n_nodes = tables.shape_dim, len(tables.kinds)
    body_nodes = [
        [k for k in range(n_nodes) if tables.node_body[k] == a] for a in range(len(parents))
    ]
    body_columns = [
        [tables.q_start[k] + i for k in nodes for i in range(_WIDTH[tables.kinds[k]])]
        for nodes in body_nodes
    ]
    levels = _by_level(parents)
    order = [a for level in levels[1:] for a in level]
    bounds = tuple(np.cumsum([0] + [len(level) for level in levels[1:]]).tolist())
    widths = tuple(max(len(body_columns[a]) for a in level) for level in levels[1:])
    position = {a: i for level in levels for i, a in enumerate(level)}
    parent_maps = tuple(
        np.eye(len(above), dtype=int)[[position[parents[a]] for a in below]]
        for above, below in zip(levels[:-1], levels[1:], strict=True)
    )
    solved = np.zeros(d, dtype=int)
    offset = 0
    for level, width in zip(levels[1:], widths, strict=True):
        for i, a in enumerate(level):
            for s, j in enumerate(body_columns[a]):
                solved[j] = offset + i * width + s
        offset += len(level) * width
    node_parents = np.array([p if p >= 0 else n_nodes for p in tables.node_parent])
    return _Levels(
        order=np.array(order, dtype=int),
        bounds=bounds,
        widths=widths,
        parents=parent_maps,
        columns=_padded([body_columns[a] for a in order], d),
        solved=solved,
        node_parents=node_parents,
        body_nodes=_padded(body_nodes, n_nodes),
    )


def covers(system) -> bool:
    """Whether the recursions compute the field of `system`: a `Multibody` whose section is
    its base, with hinges, slides, balls and welds."""
    return type(system) is Multibody and set(system.tables.kinds) <= set(_WIDTH)


def _checked_tree(system) -> Multibody:
    """`system` if the recursions cover it, else a `ValueError` naming the dense field."""
    if type(system) is not Multibody:
        raise ValueError(
            "the recursive accelerations need a `Multibody` with its section at the base, got "
            f"{type(system).__name__}: use the dense field (`bundle_geometry`)."
        )
    return system


class TreeMotion(NamedTuple):
    r"""What the passes need of a tree at $(q, \dot q)$, before the section frame's twist is known.

    **Fields** (per body, base first, section frame):

    - `inertias`: $\tilde M_a = \operatorname{Ad}_{r_a^{-1}}^T M_a \operatorname{Ad}_{r_a^{-1}}$, `(n, 6, 6)`.
    - `relative`: $W_a = \sum_{j\preceq a} Z_j\dot q_j$, the body's twist relative to the
      section frame, `(n, 6)`.
    - `joint_twists`: $x_a = W_a - W_{\text{parent}(a)}$, its joint's own twist, `(n, 6)`.
    - `drift`: $\sum_k [W_{\text{parent}(k)}, x_k] + \operatorname{Ad}_{T_k}(\partial_{\dot q}S_k)\dot q_k$
      over the body's joint factors $k$: the velocity-product acceleration of the joint with
      the section frame at rest (the last term a ball joint's $\operatorname{dexp}$), `(n, 6)`.
    - `columns`: the joint columns $Z$ (architecture §2), `(6, d)`.
    """

    inertias: Float[Array, "n 6 6"]
    relative: Float[Array, "n 6"]
    joint_twists: Float[Array, "n 6"]
    drift: Float[Array, "n 6"]
    columns: Float[Array, "6 d"]


def _through(matrix, x):
    r"""$Ex$: the rows of `x` `(n, k)` combined by a constant 0/1 matrix $E$ `(m, n)`.

    A contraction, where a gather would do: reverse mode transposes it to another, and a
    gather to a `scatter-add`, which XLA's CPU runs as a loop of kernels over the indices,
    one such loop per level of the tree.
    """
    return einsum("mn,nk->mk", matrix.astype(x.dtype), x)


def _path_sums(x, parents):
    r"""$\sum$ of `x` `(m, 6)` over each node and its ancestors (`parents`, $m$ for none), by
    pointer jumping: $\lceil\log_2\text{depth}\rceil$ gathers and sums."""
    m = x.shape[0]
    above = np.append(parents, m)
    zero = jnp.zeros((1, 6), x.dtype)
    while np.any(above[:m] != m):
        x = x + take(jnp.concatenate([x, zero]), above[:m])
        above = above[above]
    return x


def _per_row(x, table):
    r"""Rows of `x` summed by `table` `(r, c)` of row indices, `x.shape[0]` for none."""
    return jnp.sum(take(jnp.concatenate([x, jnp.zeros_like(x[:1])]), table), axis=1)


def _ball_drift(system: Multibody, q, qdot, T, ball_nodes):
    r"""$\operatorname{Ad}_{T}(\partial_{\dot\varphi}S)\dot\varphi$ of each ball joint: its
    columns $S = [J_r; \tilde aJ_r]$, $J_r = \operatorname{dexp}(\varphi)$, turning with its
    own coordinates; the rotation $R\,h$ about the joint's centre $c$, $h = \sum_l
    \dot\varphi_l(\partial_l J_r)\dot\varphi$, `(k, 6)`."""
    cols = np.array(system.tables.q_start)[ball_nodes][:, None] + np.arange(3)
    phi, phidot = take(q, cols), take(qdot, cols)
    h = einsum("kl,klij,kj->ki", phidot, so3_dexp_derivative(phi), phidot)
    R, centre = system._ball_frames(T, ball_nodes)
    w = einsum("kij,kj->ki", R, h)
    return jnp.concatenate([w, jnp.cross(centre, w)], axis=-1)


class NodeMotion(NamedTuple):
    r"""`TreeMotion`'s quantities joint factor by joint factor (node by node), which the
    reverse pass's path sums need (`_recursive_dynamics_vjp`).

    **Fields:** `inertias` and `columns` as `TreeMotion`'s; per node, `relative`
    $W_k = \sum_{j\preceq k} x_j$, `own` $x_k$ and `drift`, `(m, 6)`.
    """

    inertias: Float[Array, "n 6 6"]
    columns: Float[Array, "6 d"]
    relative: Float[Array, "m 6"]
    own: Float[Array, "m 6"]
    drift: Float[Array, "m 6"]


@functools.cache
def _node_columns(tables: Tree) -> np.ndarray:
    """Each node's shape coordinates, padded with $d$."""
    return _padded(
        [
            [tables.q_start[k] + i for i in range(_WIDTH[kind])]
            for k, kind in enumerate(tables.kinds)
        ],
        tables.shape_dim,
    )


def node_twists(system, columns, u):
    r"""$x_k = Z_k u_k$: each node's own twist at the shape velocity (or any shape vector)
    $u$, `(m, 6)`, for the joint columns $Z$ `(6, d)` of `system`'s tree."""
    return _per_row((columns * u[None, :]).T, _node_columns(system.tables))


def node_path_sums(system, x):
    r"""$\sum_{j\preceq k} x_j$ over each node's path from the root, `(m, 6)`."""
    return _path_sums(x, _levels(system.tables, system.parents).node_parents)


def node_motion(system, q: Float[Array, " d"], qdot: Float[Array, " d"]) -> NodeMotion:
    r"""The bodies' inertias, the joint columns, and each node's relative twist, own twist and
    drift at $(q, \dot q)$ (`NodeMotion`).

    **Arguments:**

    - `system`: a `Multibody` (section at the base; anything else is a `ValueError`).
    - `q`, `qdot`: the shape and its velocity, `(d,)`.

    **Returns:**

    A `NodeMotion`.
    """
    tree = _checked_tree(system)
    t = tree.tables
    levels = _levels(t, tree.parents)
    T, screw_nodes, ball_nodes, Jr = tree._node_poses(q)
    Z = tree._shape_columns(T, screw_nodes, ball_nodes, Jr)
    inertias = tree._section_inertias(take(T, t.body_last))
    own = node_twists(tree, Z, qdot)
    relative = _path_sums(own, levels.node_parents)
    parent_twists = take(jnp.concatenate([relative, jnp.zeros_like(own[:1])]), levels.node_parents)
    drift = lie.bracket(parent_twists, own)
    if len(ball_nodes):
        ball_rows = np.full(len(t.kinds), len(ball_nodes))
        ball_rows[ball_nodes] = np.arange(len(ball_nodes))
        balls = _ball_drift(tree, q, qdot, T, ball_nodes)
        drift = drift + take(jnp.concatenate([balls, jnp.zeros_like(balls[:1])]), ball_rows)
    return NodeMotion(inertias, Z, relative, own, drift)


def at_bodies(system, motion: NodeMotion) -> TreeMotion:
    """The `TreeMotion` of a `NodeMotion`: each body's relative twist at its last node, its
    joint's twist and drift summed over its nodes."""
    t = system.tables
    body_nodes = _levels(t, system.parents).body_nodes
    return TreeMotion(
        motion.inertias,
        take(motion.relative, t.body_last),
        _per_row(motion.own, body_nodes),
        _per_row(motion.drift, body_nodes),
        motion.columns,
    )


def tree_motion(system, q: Float[Array, " d"], qdot: Float[Array, " d"]) -> TreeMotion:
    r"""The bodies' inertias, relative twists and joint drifts at $(q, \dot q)$ (`TreeMotion`).

    **Arguments:**

    - `system`: a `Multibody` (section at the base; anything else is a `ValueError`).
    - `q`, `qdot`: the shape and its velocity, `(d,)`.

    **Returns:**

    A `TreeMotion`.
    """
    return at_bodies(system, node_motion(system, q, qdot))


def body_twist(motion: TreeMotion, U: Float[Array, "6"]) -> Float[Array, "6"]:
    r"""$\xi = U - A\dot q = U - I_r^{-1}\sum_a\tilde M_aW_a$ (seed 004, §2): the section frame's
    twist from the locked velocity, $B\dot q$ being the momentum of the relative motion.

    **Arguments:**

    - `motion`: the tree's `TreeMotion`; `U`: the locked velocity, `(6,)`.

    **Returns:**

    $\xi$, `(6,)`.
    """
    I_r = jnp.sum(motion.inertias, axis=0)
    relative_momentum = jnp.sum(einsum("aij,aj->ai", motion.inertias, motion.relative), axis=0)
    return U - matmul(spd_inverse_6x6(I_r), relative_momentum)


def _inverse_cholesky_factor(D):
    r"""$L^{-1}$ of SPD blocks $D = LL^T$ `(k, w, w)`, lower triangular (zeros above the
    diagonal), unrolled into elementwise work (the blocks are at most 6×6)."""
    w = D.shape[-1]
    L = {}
    for j in range(w):
        L[j, j] = jnp.sqrt(D[:, j, j] - sum(L[j, m] * L[j, m] for m in range(j)))
        for i in range(j + 1, w):
            L[i, j] = (D[:, i, j] - sum(L[i, m] * L[j, m] for m in range(j))) / L[j, j]
    X = {}
    for j in range(w):
        X[j, j] = 1.0 / L[j, j]
        for i in range(j + 1, w):
            X[i, j] = -sum(L[i, m] * X[m, j] for m in range(j, i)) / L[i, i]
    zero = jnp.zeros_like(X[0, 0])
    return jnp.stack([jnp.stack([X.get((r, c), zero) for c in range(w)], -1) for r in range(w)], -2)


class _Bodies(NamedTuple):
    r"""The bodies below the base in level order, as the passes read them: inertias
    $\tilde M$ `(n-1, 6, 6)`, bias wrenches $\operatorname{ad}^*_V\tilde MV$ and joint drifts
    $c$ `(n-1, 6)`, and the joints' columns $S$ `(n-1, w, 6)`, forces $Q$ and rotor inertias
    `(n-1, w)`, where a pad has a zero column and rotor inertia 1 (so its acceleration is 0)."""

    inertias: Array
    bias: Array
    drift: Array
    S: Array
    Q: Array
    rotor: Array


def _level_order(system: Multibody, motion: TreeMotion, xi, shape_force, levels: _Levels):
    r"""The base's inertia and bias wrench, and the other bodies' `_Bodies`, at the section
    frame's twist $\xi$: each body moves with $V = \xi + W$, and its joint drifts by
    `TreeMotion.drift` plus $[\xi, x]$."""
    V = xi[None, :] + motion.relative
    bias = lie.coad_action(V, einsum("aij,aj->ai", motion.inertias, V))
    drift = motion.drift + lie.bracket(xi[None, :], motion.joint_twists)
    dtype = shape_force.dtype
    columns = jnp.concatenate([motion.columns.T, jnp.zeros((1, 6), dtype)])
    rotor = jnp.concatenate([system.armature.astype(dtype), jnp.ones(1, dtype)])
    bodies = _Bodies(
        take(motion.inertias, levels.order),
        take(bias, levels.order),
        take(drift, levels.order),
        take(columns, levels.columns),
        take(jnp.concatenate([shape_force, jnp.zeros(1, dtype)]), levels.columns),
        take(rotor, levels.columns),
    )
    return motion.inertias[0], bias[0], bodies


class _Joint(NamedTuple):
    r"""One level's joints after the pass from the leaves: their columns $S$ `(k, w, 6)`,
    $L^{-1}$ `(k, w, w)` of $D = LL^T$, $Y = L^{-1}U^T$ `(k, w, 6)` and $z = L^{-1}u$ `(k, w)`
    (`_through_joints`)."""

    S: Array
    L_inv: Array
    Y: Array
    z: Array


def _through_joints(IA, pA, drift, S, Q, rotor):
    r"""One level's articulated inertias and biases seen from the parents, $I^a = I^A - UD^{-1}U^T$
    and $p^a = p^A + I^ac + UD^{-1}u$ with $U = I^AS$, $D = S^TI^AS + \operatorname{diag}(a)$ and
    $u = Q - S^Tp^A$, and its `_Joint`.

    Both through $D$'s Cholesky factor, $I^a = I^A - Y^TY$ and $p^a = p^A + I^ac + Y^Tz$ with
    $Y = L^{-1}U^T$, $z = L^{-1}u$: the entries of an explicit $D^{-1}$ are as large as
    $1/\lambda_{\min}(D)$, and their rounding meets $U$'s large columns in every direction,
    where $Y$'s rows carry $D$'s small pivots only as $1/\sqrt\lambda$, and only in the
    direction that is small in $U$ too. A body of mass $m$ far out on a slide below a ball
    joint makes $D$ that ill-conditioned: its eigenvalues go from the spin inertia about the
    slide's line to $m\ell^2$ at the distance $\ell$.
    """
    w = S.shape[1]
    U = einsum("kij,kwj->kwi", IA, S)
    D = einsum("kvi,kwi->kvw", S, U) + rotor[:, :, None] * jnp.eye(w, dtype=IA.dtype)[None]
    u = Q - einsum("kwi,ki->kw", S, pA)
    L_inv = _inverse_cholesky_factor(D)
    Y = einsum("kvw,kwi->kvi", L_inv, U)
    z = einsum("kvw,kw->kv", L_inv, u)
    Ia = IA - einsum("kwi,kwj->kij", Y, Y)
    pa = pA + einsum("kij,kj->ki", Ia, drift) + einsum("kwi,kw->ki", Y, z)
    return Ia, pa, _Joint(S, L_inv, Y, z)


def _from_the_leaves(levels: _Levels, base_inertia, base_bias, bodies: _Bodies):
    r"""The pass from the leaves: each level's `_Joint` (None for a level of welds) and the
    base's articulated inertia $I^A_0$ and bias $p^A_0$, $f_0 = I^A_0\mathcal A_0 + p^A_0$
    being the wrench the whole tree needs at the base's acceleration $\mathcal A_0$.

    A body's $I^A = \tilde M + \sum_{\text{children}} I^a$ and
    $p^A = \operatorname{ad}^*_V\tilde MV + \sum_{\text{children}} p^a$ (`_through_joints`).
    """
    joints = []
    below = None  # per body of this level, its children's (I^a, p^a) summed
    inertias, biases, drifts, columns, forces, rotors = (_by_levels(x, levels) for x in bodies)
    for L in reversed(range(len(levels.widths))):
        w = levels.widths[L]
        IA, pA = inertias[L], biases[L]
        if below is not None:
            IA, pA = IA + below[0], pA + below[1]
        drift = drifts[L]
        if w:
            S, Q, rotor = columns[L][:, :w], forces[L][:, :w], rotors[L][:, :w]
            Ia, pa, joint = _through_joints(IA, pA, drift, S, Q, rotor)
        else:
            Ia, pa, joint = IA, pA + einsum("kij,kj->ki", IA, drift), None
        joints.append(joint)
        below = _into_parents(Ia, pa, levels.parents[L])
    if below is None:  # the base alone
        return [], base_inertia, base_bias
    return joints[::-1], base_inertia + below[0][0], base_bias + below[1][0]


def _by_levels(x, levels: _Levels):
    r"""`x`, rows in level order, split into its levels: one `split`, which reverse mode
    transposes to one concatenation (a slice per level would transpose to a pad of all
    the rows each, work growing with the levels times the bodies)."""
    return jnp.split(x, levels.bounds[1:-1])


def _into_parents(Ia, pa, parents):
    r"""$\sum_{\text{children}} (I^a, p^a)$ for each body of the level above, through the
    transpose of the level's 0/1 matrix `parents` (`_Levels.parents`)."""
    # Kept apart level by level: without the barrier XLA fuses each level into the next,
    # recomputing the chain below it (the dog's field 139 -> 78 us; an 80-body chain
    # compiled in 3.5 min, 5 s with it).
    packed = lax.optimization_barrier(
        _through(parents.T, jnp.concatenate([Ia.reshape(-1, 36), pa], axis=1))
    )
    return packed[:, :36].reshape(-1, 6, 6), packed[:, 36:]


def _from_the_root(levels: _Levels, joints, drift, A0):
    r"""The pass from the root: $\mathcal A = \mathcal A_{\text{parent}} + c$,
    $\ddot q = D^{-1}(u - U^T\mathcal A) = L^{-T}(z - Y\mathcal A)$ (`_Joint`), then
    $\mathcal A \mathrel{+}= S\ddot q$ level by level from the base's acceleration
    $\mathcal A_0$; $\ddot q$ in coordinate order."""
    A_above = A0[None]
    solved = []
    for L, (joint, level_drift) in enumerate(zip(joints, _by_levels(drift, levels), strict=True)):
        A = _through(levels.parents[L], A_above) + level_drift
        if joint is not None:
            qddot = einsum("kvw,kv->kw", joint.L_inv, joint.z - einsum("kwi,ki->kw", joint.Y, A))
            A = A + einsum("kwi,kw->ki", joint.S, qddot)
            solved.append(qddot.reshape(-1))
        A_above = materialized(A)
    if not solved:  # welds only
        return jnp.zeros(0, A0.dtype)
    return take(jnp.concatenate(solved), levels.solved)


def uniform_field_twist(gravity, dtype) -> Float[Array, "6"]:
    r"""$(0, \gamma_b)$: a uniform field's acceleration $\gamma_b$ `(3,)` as a twist, zero
    without one (`gravity` None)."""
    if gravity is None:
        return jnp.zeros(6, dtype)
    return jnp.concatenate([jnp.zeros(3, dtype), gravity.astype(dtype)])


def driven_accelerations(
    system, motion: TreeMotion, xi, xi_dot, shape_force, gravity=None
) -> Float[Array, " d"]:
    r"""$\ddot q$ when the section frame's motion $(\xi, \dot\xi)$ is given (a held or moving base).

    The shape rows of the reference form, as `driven_shape_acceleration`: the
    articulated-body passes from the base's acceleration $\mathcal A_0 = \dot\xi$. A uniform
    field $\gamma$ acting on every body as on its mass is the same motion seen from a frame
    falling with it (seed 004, Theorem 3.4): the passes start from $\dot\xi - (0, \gamma_b)$.

    **Arguments:**

    - `system`: the `Multibody`; `motion`: its `tree_motion` at $(q, \dot q)$.
    - `xi`, `xi_dot`: the section frame's body velocity and its rate, `(6,)`.
    - `shape_force`: $Q_H$ of the other effects, `(d,)`.
    - `gravity`: $\gamma_b = R^T\gamma$, the field's acceleration in section axes, `(3,)`
      (`Gravity` with the inertial mass and no centre offset, whose forces are then left
      out of $Q_H$), or None.

    **Returns:**

    $\ddot q$, `(d,)`.
    """
    levels = _levels(system.tables, system.parents)
    base_inertia, base_bias, bodies = _level_order(system, motion, xi, shape_force, levels)
    joints, _, _ = _from_the_leaves(levels, base_inertia, base_bias, bodies)
    A0 = xi_dot - uniform_field_twist(gravity, xi_dot.dtype)
    return _from_the_root(levels, joints, bodies.drift, A0)


def floating_accelerations(
    system, motion: TreeMotion, U, xi, wrench, shape_force, gravity=None
) -> tuple[Float[Array, "6"], Float[Array, " d"]]:
    r"""$\dot U$ (2.7) and $\ddot q$ (2.6) of a free shape on a floating base.

    The base's acceleration solves $I^A_0\dot\xi + p^A_0 = F_b$ after the pass from the
    leaves; $\dot U$ is the group equation,
    $I_r\dot U = F_b - \operatorname{ad}^*_\xi I_rU - (\partial_{\dot q}I_r)U$ with
    $(\partial_{\dot q}I_r)U = -\sum_a(\operatorname{ad}^T_{W_a}\tilde M_aU + \tilde M_a[W_a, U])$.
    A uniform field adds $(0, \gamma_b)$ to $\dot U$ and to the base's acceleration, and
    nothing to the joints' (seed 004, Theorem 3.4).

    **Arguments:**

    - `system`: the `Multibody`; `motion`: its `tree_motion` at $(q, \dot q)$.
    - `U`: the locked velocity; `xi`: the section frame's twist, `body_twist(motion, U)`.
    - `wrench`: $F_b$; `shape_force`: $Q_H$ (in the variables $(\xi, \dot q)$), of the
      other effects.
    - `gravity`: as in `driven_accelerations`.

    **Returns:**

    `(Udot, qddot)`, shapes `(6,)` and `(d,)`.
    """
    levels = _levels(system.tables, system.parents)
    base_inertia, base_bias, bodies = _level_order(system, motion, xi, shape_force, levels)
    joints, IA0, pA0 = _from_the_leaves(levels, base_inertia, base_bias, bodies)
    qddot = _from_the_root(levels, joints, bodies.drift, spd_solve(IA0, wrench - pA0))
    Udot = locked_rate(motion, U, xi, wrench) + uniform_field_twist(gravity, U.dtype)
    return Udot, qddot


def locked_rate(motion: TreeMotion, U, xi, wrench) -> Float[Array, "6"]:
    r"""$\dot U = I_r^{-1}\big(F_b - \operatorname{ad}^*_\xi I_rU - (\partial_{\dot q}I_r)U\big)$,
    the rate of the total momentum $I_rU$ less the turning of $I_r$ (module docstring), a
    uniform field's acceleration left out.

    **Arguments:**

    - `motion`: the tree's `TreeMotion`; `U`: the locked velocity; `xi`: the section frame's
      twist, `body_twist(motion, U)`; `wrench`: $F_b$.

    **Returns:**

    $\dot U$, `(6,)`.
    """
    M, W = motion.inertias, motion.relative
    I_r = jnp.sum(M, axis=0)
    MU = einsum("aij,j->ai", M, U)
    turning = einsum("aij,aj->ai", M, lie.bracket(W, U[None, :])) - lie.coad_action(W, MU)
    rhs = wrench - lie.coad_action(xi, matmul(I_r, U)) + jnp.sum(turning, axis=0)
    return matmul(spd_inverse_6x6(I_r), rhs)


def metric_solve(system, inertias, columns, shape_rhs, *, floating: bool):
    r"""$G^{-1}[0; b]$ by the articulated-body passes at rest: the accelerations that the
    shape forces $b$ alone give the tree at rest, a metric solve in $O(n)$ work.

    The passes of `floating_accelerations` (`driven_accelerations` with the base held)
    with no velocity, drift, bias or base wrench, so that $G\,a = [0; b]$ with
    $a = [\mathcal A_0; \ddot q]$ (the base's $\mathcal A_0 = 0$ when held).

    **Arguments:**

    - `system`: the `Multibody`; `inertias`, `columns`: its bodies' `TreeMotion.inertias`
      and joint columns $Z$ at the shape.
    - `shape_rhs`: $b$, `(d,)`.
    - `floating`: whether the base is free (else held).

    **Returns:**

    `(base, shape)`: $\mathcal A_0$ `(6,)` and the shape part `(d,)`.
    """
    levels = _levels(system.tables, system.parents)
    zero = jnp.zeros((inertias.shape[0], 6), shape_rhs.dtype)
    at_rest = TreeMotion(inertias, zero, zero, zero, columns)
    base_inertia, base_bias, bodies = _level_order(
        system, at_rest, jnp.zeros(6, shape_rhs.dtype), shape_rhs, levels
    )
    joints, IA0, pA0 = _from_the_leaves(levels, base_inertia, base_bias, bodies)
    base = spd_solve(IA0, -pA0) if floating else jnp.zeros(6, shape_rhs.dtype)
    return base, _from_the_root(levels, joints, bodies.drift, base)
