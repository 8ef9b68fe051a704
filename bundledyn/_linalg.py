"""Small dense inverses in closed form: a handful of fused elementwise kernels, no LAPACK call.

On XLA's CPU a LAPACK factorization of a 6×6 matrix costs microseconds of call overhead
(an LU solve against the identity ~2.5 µs, with a pivot loop; a Cholesky ~4 µs), more than
the whole closed form below (~0.6 µs, measured inside a compiled loop), and under `vmap` it
runs one factorization per instance. The closed form is elementwise and batches for free.
"""

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

# adj(M)[i, j] = M[j+1, i+1] M[j+2, i+2] - M[j+2, i+1] M[j+1, i+2] (indices mod 3): one gather
# pattern per factor, so the adjugate is a single fused elementwise kernel.
_I, _J = np.indices((3, 3))
_NEXT, _AFTER = (_J + 1) % 3, (_J + 2) % 3
_NEXT_T, _AFTER_T = (_I + 1) % 3, (_I + 2) % 3


def inverse_3x3(M: Float[Array, "3 3"]) -> Float[Array, "3 3"]:
    """$M^{-1} = \\operatorname{adj}(M)/\\det M$ (the rows of the adjugate are cross products of columns).

    **Arguments:**

    - `M`: an invertible 3×3 matrix.

    **Returns:**

    $M^{-1}$, with rows $(c_1\\times c_2,\\ c_2\\times c_0,\\ c_0\\times c_1)/(c_0\\cdot(c_1\\times c_2))$
    for the columns $c_j$ of $M$.
    """
    adjugate = M[_NEXT, _NEXT_T] * M[_AFTER, _AFTER_T] - M[_AFTER, _NEXT_T] * M[_NEXT, _AFTER_T]
    return adjugate / jnp.dot(M[:, 0], adjugate[0])


def spd_inverse_6x6(M: Float[Array, "6 6"]) -> Float[Array, "6 6"]:
    """Inverse of a symmetric positive definite 6×6 matrix by its 3×3 blocks (Schur complement).

    With $M = \\begin{bmatrix} P & Q \\\\ Q^T & D\\end{bmatrix}$, $K = QD^{-1}$ and the Schur
    complement $S = P - KQ^T$ (SPD whenever $M$ is),

    $$M^{-1} = \\begin{bmatrix} S^{-1} & X \\\\ X^T & D^{-1} - K^T X\\end{bmatrix},\\quad X = -S^{-1}K.$$

    For a spatial inertia (angular first; every locked inertia is one) $D = m\\mathbf 1$ and $S$
    is the rotational inertia about the centre of mass, so both 3×3 inverses are as well
    conditioned as the body and the result is as accurate as LAPACK's (tests: forward error
    within 4 κ ε up to κ ~ 1e10). For an arbitrary SPD matrix the form is not backward
    stable (forward error ~80 κ ε measured at κ = 1e6).

    **Arguments:**

    - `M`: symmetric positive definite, shape `(6, 6)` (only the blocks $P$, $Q$, $D$ are read).

    **Returns:**

    $M^{-1}$, symmetric by construction.
    """
    P, Q, D = M[:3, :3], M[:3, 3:], M[3:, 3:]
    D_inv = inverse_3x3(D)
    K = Q @ D_inv
    S_inv = inverse_3x3(P - K @ Q.T)
    X = -S_inv @ K
    return jnp.block([[S_inv, X], [X.T, D_inv - K.T @ X]])
