"""Closed-form small inverses against LAPACK, with derivatives against finite differences."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg
from systems import SYSTEMS

import bundledyn as bd
from bundledyn._linalg import (
    einsum,
    expm,
    inverse_3x3,
    matmul,
    spd_inverse_6x6,
    spd_solve,
    take,
)
from bundledyn._systems._rigid_body import spatial_inertia


def _random_spd(rng, n, condition):
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return (Q * np.geomspace(1.0, 1.0 / condition, n)) @ Q.T


def _spatial_inertias(rng):
    """Spatial inertias about points near and far from bodies, slender and flat ones included
    (the parallel-axis term then dominates the angular block), and composites of several."""
    out = []
    for _ in range(24):
        Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
        principal = np.exp(rng.uniform(np.log(1e-6), 0.0, 3))
        com = rng.standard_normal(3) * 10.0 ** rng.uniform(-2, 1)
        mass = np.exp(rng.standard_normal())
        out.append(np.asarray(spatial_inertia(mass, com, (Q * principal) @ Q.T)))
    out += [sum(out[i : i + 4]) for i in range(0, 24, 4)]
    return out


def _check_inverse(M, inv, factor):
    """Forward error within `factor` κ ε of LAPACK's inverse (what `I_r⁻¹ @ v` inherits)."""
    bound = factor * np.linalg.cond(M) * np.finfo(float).eps * np.abs(np.linalg.inv(M)).max()
    assert np.abs(inv - np.linalg.inv(M)).max() < bound
    assert np.abs(inv - inv.T).max() < bound


def test_spatial_inertia_inverse_matches_lapack():
    """Locked inertias are spatial inertias: the 3×3 blocks are then as well conditioned as the
    body, and the closed form is as accurate as LAPACK's LU (condition numbers up to ~1e10)."""
    inverse = jax.jit(spd_inverse_6x6)
    for M in _spatial_inertias(np.random.default_rng(3)):
        _check_inverse(M, np.asarray(inverse(M)), factor=4.0)


def test_spd_inverse_of_a_generic_matrix():
    """Any SPD matrix with κ ≤ 1e3 to 10 κ ε. The Schur/adjugate form is not backward stable:
    for a matrix that mixes its conditioning across the blocks the error grows (measured
    ~80 κ ε at κ = 1e6), which locked inertias never do (see above)."""
    rng = np.random.default_rng(7)
    for condition in (1.0, 1e3):
        for _ in range(16):
            M = _random_spd(rng, 6, condition)
            _check_inverse(M, np.asarray(spd_inverse_6x6(M)), factor=10.0)


def test_inverse_3x3_matches_lapack():
    rng = np.random.default_rng(4)
    for _ in range(16):
        M = rng.standard_normal((3, 3))
        np.testing.assert_allclose(inverse_3x3(M), np.linalg.inv(M), rtol=1e-12, atol=1e-12)


def test_spd_inverse_derivatives_vs_finite_differences():
    """d(M⁻¹) = -M⁻¹ dM M⁻¹ (closed form), forward and reverse mode, and finite differences."""
    rng = np.random.default_rng(5)
    M, dM = _random_spd(rng, 6, 10.0), rng.standard_normal((6, 6))
    dM = dM + dM.T
    _, tangent = jax.jvp(spd_inverse_6x6, (jnp.asarray(M),), (jnp.asarray(dM),))
    inv = np.linalg.inv(M)
    np.testing.assert_allclose(tangent, -inv @ dM @ inv, rtol=1e-10, atol=1e-12)
    h = 1e-6
    fd = (spd_inverse_6x6(M + h * dM) - spd_inverse_6x6(M - h * dM)) / (2 * h)
    np.testing.assert_allclose(tangent, fd, rtol=1e-6, atol=1e-8)
    W = rng.standard_normal((6, 6))
    grad = jax.grad(lambda A: jnp.sum(W * spd_inverse_6x6(A)))(jnp.asarray(M))
    np.testing.assert_allclose(np.sum(grad * dM), np.sum(W * tangent), rtol=1e-12)


def test_spd_inverse_vmaps():
    rng = np.random.default_rng(6)
    Ms = np.stack([_random_spd(rng, 6, 100.0) for _ in range(8)])
    np.testing.assert_allclose(
        jax.vmap(spd_inverse_6x6)(Ms), np.linalg.inv(Ms), rtol=1e-11, atol=1e-12
    )


# Both sides of the unrolling limit (6): the unrolled Cholesky and LAPACK's.
_SOLVE_SIZES = (1, 4, 6, 7)


@pytest.mark.parametrize("d", _SOLVE_SIZES)
def test_spd_solve_is_backward_stable(d):
    """Cholesky's residual is ~ε‖M‖‖x‖ whatever the conditioning (κ up to 1e12), as LAPACK's."""
    rng = np.random.default_rng(d)
    solve = jax.jit(spd_solve)
    for condition in (1.0, 1e4, 1e8, 1e12):
        M, b = _random_spd(rng, d, condition), rng.standard_normal(d)
        x = np.asarray(solve(M, b))
        residual = np.abs(M @ x - b).max()
        assert residual < 8 * d * np.finfo(float).eps * np.abs(M).max() * np.abs(x).max()
        np.testing.assert_allclose(x, np.linalg.solve(M, b), rtol=8 * condition * 1e-16 * d)


@pytest.mark.parametrize("d", _SOLVE_SIZES)
def test_spd_solve_derivatives_vs_finite_differences(d):
    """dx = M⁻¹(db - dM x), forward and reverse mode agreeing, against central differences;
    and no LAPACK call in the unrolled range, forward or reverse."""
    rng = np.random.default_rng(10 + d)
    M, b = jnp.asarray(_random_spd(rng, d, 10.0)), jnp.asarray(rng.standard_normal(d))
    dM, db = rng.standard_normal((d, d)), jnp.asarray(rng.standard_normal(d))
    dM = jnp.asarray(dM + dM.T)
    x, tangent = jax.jvp(spd_solve, (M, b), (dM, db))
    np.testing.assert_allclose(tangent, np.linalg.solve(M, db - dM @ x), rtol=1e-12, atol=1e-13)
    h = 1e-6
    fd = (spd_solve(M + h * dM, b + h * db) - spd_solve(M - h * dM, b - h * db)) / (2 * h)
    np.testing.assert_allclose(tangent, fd, rtol=1e-7, atol=1e-9)
    w = jnp.asarray(rng.standard_normal(d))
    gM, gb = jax.grad(lambda M, b: w @ spd_solve(M, b), argnums=(0, 1))(M, b)
    np.testing.assert_allclose(jnp.sum(gM * dM) + gb @ db, w @ tangent, rtol=1e-12)
    hlo = jax.jit(jax.grad(lambda M, b: jnp.sum(jnp.sin(spd_solve(M, b))))).lower(M, b)
    assert ("custom-call" in hlo.compile().as_text()) == (d > 6)


def test_spd_solve_vmaps():
    rng = np.random.default_rng(11)
    Ms = np.stack([_random_spd(rng, 5, 100.0) for _ in range(8)])
    bs = rng.standard_normal((8, 5))
    np.testing.assert_allclose(
        jax.vmap(spd_solve)(Ms, bs), np.linalg.solve(Ms, bs[..., None])[..., 0], rtol=1e-12
    )


_CONTRACTIONS = [
    ("...ij,...jk->...ik", [(5, 3, 3), (1, 3, 3)]),
    ("...ij,...jk->...ik", [(3, 3), (2, 3, 3)]),
    ("...ij,j->...i", [(4, 6, 6), (6,)]),
    ("j,...jk->...k", [(3,), (2, 3, 4)]),
    ("kij,kj->ik", [(4, 6, 6), (4, 6)]),
    ("aij,ajk,alk->ail", [(5, 3, 3), (5, 3, 3), (5, 3, 3)]),
    ("il,ml,al->mai", [(6, 4), (2, 4), (5, 4)]),
    ("...i,ij->...j", [(14,), (14, 6)]),
    ("...i,ij->...j", [(3, 14), (14, 0)]),
    ("al,aij->lij", [(20, 19), (20, 6, 6)]),  # above the limit: jnp.einsum
    ("ii->i", [(3, 3)]),  # a repeated index: jnp.einsum
]


@pytest.mark.parametrize("subscripts, shapes", _CONTRACTIONS)
def test_small_einsum_matches_jnp_einsum(subscripts, shapes):
    rng = np.random.default_rng(0)
    operands = [jnp.asarray(rng.standard_normal(s)) for s in shapes]
    expected = jnp.einsum(subscripts, *operands, precision="highest")
    out = einsum(subscripts, *operands)
    assert out.shape == expected.shape and out.dtype == expected.dtype
    np.testing.assert_allclose(out, expected, rtol=1e-14, atol=1e-14)


@pytest.mark.parametrize("subscripts, shapes", _CONTRACTIONS)
def test_small_einsum_derivatives_match_jnp_einsum(subscripts, shapes):
    """Forward and reverse mode through the custom JVP, and second order for three operands."""
    rng = np.random.default_rng(2)
    operands = [jnp.asarray(rng.standard_normal(s)) for s in shapes]
    argnums = tuple(range(len(operands)))
    order = jax.hessian if len(operands) == 3 else jax.jacfwd

    @functools.partial(jax.jit, static_argnums=0)
    def derivatives(f, operands):
        loss = lambda *x: jnp.sum(jnp.sin(f(subscripts, *x)))  # noqa: E731
        return order(loss, argnums)(*operands), jax.grad(loss, argnums)(*operands)

    reference = functools.partial(jnp.einsum, precision="highest")
    got, want = derivatives(einsum, operands), derivatives(reference, operands)
    jax.tree.map(lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13), got, want)


def test_small_einsum_gradient_has_no_pad():
    """Its reverse mode is a broadcast product and a sum: transposing the forward pass's
    explicit adds would give one `pad` per contracted entry (`_fused_einsum_jvp`)."""
    a = jnp.ones((5, 3, 3))
    grad = jax.grad(lambda a: jnp.sum(jnp.sin(matmul(a, a))))
    assert " pad(" not in jax.jit(grad).lower(a).compile().as_text()


def test_inverse_gradient_has_no_scatter():
    """The reverse mode of the closed-form inverses is products, -M⁻¹ dM M⁻¹: the
    adjugate's gathers would transpose into scatter-adds."""
    M = jnp.asarray(_random_spd(np.random.default_rng(3), 6, 10.0))
    grad = jax.grad(lambda M: jnp.sum(jnp.sin(spd_inverse_6x6(M))))
    assert "scatter" not in str(jax.make_jaxpr(grad)(M))


_TAKES = {
    "identity": ([0, 1, 2, 3, 4], 0),
    "shift": ([4, 0, 1, 2], 0),
    "runs and repeats": ([3, 4, 1, 1, 2], 1),
    "2-d indices": ([[1, 2, 3], [0, 1, 2]], 0),
    "negative axis": ([2, 0], -1),
    "empty": (np.zeros(0, int), 0),
    "more runs than slices": (np.random.default_rng(3).permutation(np.arange(40) % 5), 0),
}


@pytest.mark.parametrize("case", _TAKES)
def test_take_is_jnp_take_and_differentiates_as_it(case):
    indices, axis = _TAKES[case]
    indices = np.asarray(indices)
    x = jnp.asarray(np.random.default_rng(5).standard_normal((5, 6, 3)))
    np.testing.assert_array_equal(take(x, indices, axis), jnp.take(x, indices, axis))
    grads = [
        jax.grad(lambda x, f=f: jnp.sum(jnp.sin(f(x, indices, axis)) ** 2))(x)
        for f in (take, jnp.take)
    ]
    np.testing.assert_allclose(*grads, rtol=1e-15, atol=1e-15)


@pytest.mark.parametrize("name", ["mjcf_chain5", "tree4"])
def test_tree_field_reverse_mode_has_no_scatter(name):
    """The dense field's constant indexing into the tree is `take`'s slices: a gather's
    transpose, a scatter-add, is a loop on XLA's CPU, which slows the field's VJP."""
    scene = bd.Scene(SYSTEMS[name](), algorithm=bd.DenseField())
    d = scene.system.shape_dim
    state = bd.State(jnp.eye(4), 0.1 * jnp.ones(d), 0.2 * jnp.ones(6), 0.3 * jnp.ones(d))
    term = bd.SceneTerm(scene)
    y = term.encode(0.0, state)
    vjp = lambda y: jax.vjp(lambda y: term.vf(0.0, y, None), y)[1](y)  # noqa: E731
    assert "scatter" not in str(jax.make_jaxpr(vjp)(y))


def test_small_einsum_is_fused_elementwise_work():
    """No `dot` in the compiled product of two 6×6 matrices (the point of the helper)."""
    a = jnp.ones((6, 6))
    text = jax.jit(lambda a: matmul(a, a.T)).lower(a).compile().as_text()
    assert " dot(" not in text
    big = jnp.ones((20, 19))
    text = jax.jit(lambda p: einsum("al,aij->lij", p, jnp.ones((20, 6, 6)))).lower(big)
    assert "dot_general" in text.as_text()


def test_products_per_body_fuse_and_sums_over_bodies_do_not():
    """A 6×6 by 6×6 product for each of 87 bodies is fused work (a batched `dot` of them
    is a kernel dearer than the work); a sum over the bodies stays a `dot`."""
    M, v = jnp.ones((87, 6, 6)), jnp.ones((87, 6))
    per_body = jax.jit(lambda M: matmul(M, M)).lower(M).compile()
    assert " dot(" not in per_body.as_text()
    over_bodies = jax.jit(lambda M, v: einsum("kij,kj->i", M, v)).lower(M, v)
    assert "dot_general" in over_bodies.as_text()


def test_take_gathers_past_a_few_runs_and_slices_below():
    """Many runs (a bushy tree's parents) are one gather, whose transpose does not grow
    with the runs; a few runs are slices, which transpose to pads."""
    x = jnp.ones((40, 3))
    many = np.random.default_rng(3).permutation(40)
    assert "gather" in str(jax.make_jaxpr(lambda x: take(x, many))(x))
    assert "gather" not in str(jax.make_jaxpr(lambda x: take(x, np.r_[5:40, 0:5]))(x))


def test_matmul_follows_jnp_matmul_and_its_derivatives():
    rng = np.random.default_rng(1)
    for shape_a, shape_b in [
        ((4, 4), (4, 4)),
        ((5, 4, 4), (5, 4, 4)),
        ((6, 6), (6,)),
        ((3,), (3, 3)),
    ]:
        a, b = rng.standard_normal(shape_a), rng.standard_normal(shape_b)
        np.testing.assert_allclose(matmul(a, b), np.matmul(a, b), rtol=1e-14, atol=1e-14)
        loss = lambda a, b, f: jnp.sum(jnp.sin(f(a, b)))  # noqa: E731
        for argnum in (0, 1):
            got = jax.grad(loss, argnum)(a, b, matmul)
            want = jax.grad(loss, argnum)(a, b, jnp.matmul)
            np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-14)
    vmapped = jax.vmap(matmul)(rng.standard_normal((7, 6, 6)), rng.standard_normal((7, 6)))
    assert vmapped.shape == (7, 6)


EXPM_NORMS = (1e-12, 1e-3, 0.25, 0.3, 1.0, 7.0, 60.0, 250.0)  # ‖S‖∞: no squaring up to 1/4


def _matrices_of_norm(rng, norm, count=20):
    """Symmetric (the affine body's stretch) and general 3×3 matrices with ‖S‖∞ = norm."""
    out = []
    for i in range(count):
        M = rng.standard_normal((3, 3))
        M = M + M.T if i % 2 else M
        out.append(M * norm / np.abs(M).sum(axis=1).max())
    return np.stack(out)


def test_expm_matches_scipy():
    """Relative error against SciPy's expm within 4× that of `jax.scipy.linalg.expm` (the
    problem's own conditioning grows with the norm) or 4 ulps, norm by norm."""
    ours, theirs = (jax.jit(jax.vmap(f)) for f in (expm, jax.scipy.linalg.expm))
    rng = np.random.default_rng(7)
    for norm in EXPM_NORMS:
        M = _matrices_of_norm(rng, norm)
        ref = np.stack([scipy.linalg.expm(m) for m in M])
        scale = np.abs(ref).max(axis=(1, 2))
        errors = [np.abs(f(M) - ref).max(axis=(1, 2)) / scale for f in (ours, theirs)]
        assert errors[0].max() <= 4 * max(errors[1].max(), np.finfo(float).eps), norm


# First derivatives, each compiled once. (The second ones, which the affine body's metric
# takes, are checked against its closed-form jet in test_geometry.)
EXPM_DERIVATIVES = [
    tuple(jax.jit(derivative(f)) for f in (expm, jax.scipy.linalg.expm))
    for derivative in (jax.jacfwd, jax.jacrev)
]


def test_expm_derivatives_match_jax_scipy_expm():
    """Forward and reverse derivatives against those of `jax.scipy.linalg.expm` (Padé, LU),
    at zero, across a squaring boundary (‖S‖∞ = 1/4, 1/2) and at larger norms."""
    rng = np.random.default_rng(3)
    for norm in (0.0, 0.25, 0.5, 3.0, 40.0):
        M = _matrices_of_norm(rng, max(norm, 1.0), 2)[1] * (norm / max(norm, 1.0))
        for ours, theirs in EXPM_DERIVATIVES:
            D, ref = ours(M), theirs(M)
            assert np.all(np.isfinite(D))
            np.testing.assert_allclose(D, ref, rtol=0, atol=1e-13 * np.abs(ref).max())


def test_expm_at_zero_and_past_its_range():
    """At S = 0 (where the scaling's log2 ‖S‖ is singular) e^S = 1 and its derivative is the
    identity map, exactly; past ‖S‖∞ = 256 the result is NaN, not a wrong number."""
    zero = jnp.zeros((3, 3))
    np.testing.assert_array_equal(expm(zero), np.eye(3))
    np.testing.assert_array_equal(jax.jacrev(expm)(zero), np.eye(9).reshape(3, 3, 3, 3))
    assert np.all(np.isnan(expm(jnp.diag(jnp.array([300.0, 0.0, 0.0])))))
    assert np.all(np.isfinite(expm(jnp.diag(jnp.array([256.0, 0.0, 0.0])))))
