r"""Named directions of the inertial parameters that motion cannot see.

Mass that a joint's motion carries identically on both of its bodies can be moved from one
to the other without changing any motion: the "regrouping" of robot identification
(Mayeda, Hirose & Osuka 1990; Khalil & Dombre). In pseudo-inertias (a point mass $\mu$ at
$x$ adds $\mu\,[x; 1][x; 1]^T$) the transfers are, with $T$ the child's home placement in
its parent and $\delta$ added to the child and $-T\delta T^T$ to the parent:

- a hinge: mass on its axis line $a + sk$, three directions (the moments $\int ds$,
  $\int s\,ds$, $\int s^2ds$ along the line: $uu^T$, $uw^T + wu^T$, $ww^T$ with
  $u = [a; 1]$, $w = [k; 0]$);
- a ball or universal joint: a point mass at its centre, one direction;
- a slide: second moments without mass (the two bodies turn together), six directions;
- a weld: everything, ten directions.

Besides these, the overall mass scale (`_gauge`), and each body's rotational inertia about
its centre of mass when nothing rotates it in an informative way, are named.
"""

import jax
import jax.numpy as jnp
import numpy as np

from .._systems._multibody import Multibody, Resectioned
from .._systems._pseudo_inertia import pseudo_inertia_from_log_cholesky
from ._parameters import Parameters

__all__ = ["named_directions"]


def _base_tree(system):
    if isinstance(system, Resectioned):
        return system.tree
    return system if isinstance(system, Multibody) else None


def _joint_geometry(tree: Multibody, body: int):
    """The kind of the joint of `body` ('hinge', 'slide', 'point', 'weld' or None) and its
    axis point, direction or centre in the child frame."""
    t = tree.tables
    nodes = [k for k, b in enumerate(t.node_body) if b == body]
    kinds = [t.kinds[k] for k in nodes]
    if kinds == ["fixed"]:
        return "weld", None
    if kinds == ["ball"]:
        return "point", np.asarray(tree.ball_anchors[t.factor_index[nodes[0]]])
    screws = [np.asarray(tree.screw_axes[t.factor_index[k]]) for k in nodes]
    if kinds == ["screw"]:
        w, v = screws[0][:3], screws[0][3:]
        if np.linalg.norm(w) < 1e-12:
            return "slide", v
        return "hinge", (np.cross(w, v), w)
    if kinds == ["screw", "screw"]:
        (w1, v1), (w2, v2) = ((s[:3], s[3:]) for s in screws)
        a1, a2 = np.cross(w1, v1), np.cross(w2, v2)
        n = np.cross(w1, w2)
        if np.linalg.norm(n) > 1e-8 and abs(np.dot(a2 - a1, n)) < 1e-10 * (1 + np.linalg.norm(a1)):
            s, *_ = np.linalg.lstsq(np.stack([w1, -w2], 1), a2 - a1, rcond=None)
            return "point", a1 + s[0] * w1
    return None, None


def _transfers(kind, geometry):
    """The pseudo-inertia changes δ of the child that a joint of this kind cannot see."""
    if kind == "weld":
        basis = []
        for i in range(4):
            for j in range(i, 4):
                E = np.zeros((4, 4))
                E[i, j] = E[j, i] = 1.0
                basis.append(E)
        return basis
    if kind == "point":
        u = np.append(geometry, 1.0)
        return [np.outer(u, u)]
    if kind == "hinge":
        a, k = geometry
        u, w = np.append(a, 1.0), np.append(k, 0.0)
        return [np.outer(u, u), np.outer(u, w) + np.outer(w, u), np.outer(w, w)]
    if kind == "slide":
        basis = []
        for i in range(3):
            for j in range(i, 3):
                E = np.zeros((4, 4))
                E[i, j] = E[j, i] = 1.0
                basis.append(E)
        return basis
    return []


def _padded(coordinates):
    """Ten log-Cholesky coordinates of seven (a centre fixed at the origin) or ten."""
    return jnp.concatenate([coordinates, jnp.zeros(10 - coordinates.shape[0], coordinates.dtype)])


@jax.jit
def _log_cholesky_jacobians(coordinates):
    r"""$\partial P/\partial\theta$ of each body, `(k, 4, 4, n)` for `coordinates` `(k, n)`:
    finite however degenerate the body."""
    return jax.vmap(jax.jacfwd(lambda c: pseudo_inertia_from_log_cholesky(_padded(c))))(coordinates)


def named_directions(parameters: Parameters, theta) -> dict:
    r"""Directions of $\theta$ with a physical name, each a `(size,)` array: the joints'
    regroupings (module docstring) between free bodies, the overall mass scale and each
    free body's rotational inertia scale."""
    system = parameters.system
    free = list(parameters.bodies)
    n = 7 if system.fixed_centres else 10
    P = parameters.pseudo_inertias(theta)

    coordinates = jnp.asarray(theta)[: len(free) * n].reshape(len(free), n)
    forward = np.asarray(_log_cholesky_jacobians(coordinates))

    def direction(delta):
        """θ-direction of the pseudo-inertia change `delta`, `(k, 4, 4)` over free bodies."""
        out = np.zeros(parameters.size)
        for i, jacobian in enumerate(forward):
            step = np.linalg.lstsq(jacobian.reshape(16, n), delta[i].reshape(16), rcond=None)[0]
            out[i * n : (i + 1) * n] = step
        return out

    names = parameters.body_names
    directions = {}
    overall = direction(np.asarray(P))
    overall[len(free) * n :] = 1.0  # joint constants scale with the masses
    directions["the overall mass scale (every mass, inertia and joint constant by one factor)"] = (
        overall
    )
    for i, b in enumerate(free):
        delta = np.zeros((len(free), 4, 4))
        m = float(P[i, 3, 3])
        h = np.asarray(P[i, :3, 3])
        delta[i, :3, :3] = np.asarray(P[i, :3, :3]) - np.outer(h, h) / m
        directions[f"the scale of {names[b]}'s inertia about its centre of mass"] = direction(delta)
    tree = _base_tree(system)
    if tree is None:
        return directions
    for i, b in enumerate(free):
        parent = tree.parents[b]
        if parent not in free:
            continue
        kind, geometry = _joint_geometry(tree, b)
        if kind is None:
            continue
        T = np.asarray(tree.placement[b])
        for k, delta_child in enumerate(_transfers(kind, geometry)):
            delta = np.zeros((len(free), 4, 4))
            delta[i] = delta_child
            delta[free.index(parent)] = -T @ delta_child @ T.T
            label = {
                "hinge": ("mass on the axis of", ("", " (its first moment along the axis)",
                                                   " (its second moment along the axis)")[k]),
                "point": ("a point mass at the centre of", ""),
                "slide": ("second moments (no mass) across", ""),
                "weld": ("mass across", ""),
            }[kind]  # fmt: skip
            joint = f"the joint of {names[b]}"
            directions[f"{label[0]} {joint}, shared by {names[b]} and {names[parent]}{label[1]}"
                       + (f" [{k}]" if kind in ("slide", "weld") else "")] = direction(delta)  # fmt: skip
    return directions
