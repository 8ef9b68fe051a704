r"""The static tables of a tree of bodies: its joint factors ("nodes"), their coordinates and paths.

Everything here is NumPy and hashable: it is the static structure of a `Multibody`, part
of the jit cache key, and indexes the batched arrays of the kinematics and the metric.
"""

import functools
from typing import NamedTuple

import numpy as np


class Tree(NamedTuple):
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


def tree_tables(links, n_bodies):
    """Static index tables of the tree of joint factors ("nodes").

    Each body owns one node per elementary joint factor (one node if it has none); a
    node's parent is the previous node of its body or the last node of the parent body.
    """
    kinds, factor_index, q_start, node_body, node_parent, first = [], [], [], [], [], []
    screws, anchors = [], []
    body_last = [0]
    kinds.append("fixed")
    factor_index.append(-1)
    q_start.append(0)
    node_body.append(0)
    node_parent.append(-1)
    first.append(False)
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
                factor_index.append(len(screws))
                screws.append(value)
                qi += 1
            elif kind == "ball":
                factor_index.append(len(anchors))
                anchors.append(value)
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
    tree = Tree(
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


@functools.cache
def column_tables(t: Tree) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
