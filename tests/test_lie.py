"""Tests of `bundledyn.lie`: conventions, group axioms, dexp, derivatives at the singular
angles, rotation parameterizations, batching.

Test data are numpy arrays (no compilation); every check runs inside one jitted helper
per family, with the special angles passed as data, so each helper compiles once.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg

from bundledyn import lie
from bundledyn._lie._so3 import so3_dexp_derivative, so3_dexp_second_derivative_along

PI = np.pi
# θ = 0, tiny, in the small-angle log branch, on both sides of the Taylor switch (θ² = 1),
# generic, near π
SPECIAL = (0.0, 1e-9, 0.05, 0.99, 1.01, 2.5, PI - 1e-7)
SPECIAL_IDS = ("0", "1e-9", "0.05", "0.99", "1.01", "2.5", "pi-1e-7")
N = 8  # random elements per angle
_E = np.eye(3)


@pytest.fixture
def rng(key):
    """numpy generator seeded from the session's jax key (data made without compiling)."""
    return np.random.default_rng(np.asarray(jax.random.key_data(key)).tolist())


def _unit(rng, shape):
    x = rng.standard_normal(tuple(shape) + (3,))
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def _rotvecs(rng, thetas):
    thetas = np.asarray(thetas, dtype=float)
    return thetas[..., None] * _unit(rng, thetas.shape)


def _twists(rng, theta, n=N):
    """n twists with |ω| = theta and random v."""
    return np.concatenate([_rotvecs(rng, np.full(n, theta)), rng.standard_normal((n, 3))], -1)


def _np_hat(x):
    x = np.asarray(x)
    w = x[..., :3]
    W = np.zeros(w.shape[:-1] + (3, 3))
    W[..., 0, 1], W[..., 0, 2], W[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    W = W - np.swapaxes(W, -1, -2)
    if x.shape[-1] == 3:
        return W
    X = np.zeros(x.shape[:-1] + (4, 4))
    X[..., :3, :3] = W
    X[..., :3, 3] = x[..., 3:]
    return X


def _expm(A):
    """Reference matrix exponential (scipy), batched over leading axes."""
    A = np.asarray(A)
    flat = A.reshape((-1,) + A.shape[-2:])
    return np.stack([scipy.linalg.expm(a) for a in flat]).reshape(A.shape)


def _maxabs(x):
    return jnp.max(jnp.abs(x))


def _less_one(A):
    """A batch of square matrices minus the identity."""
    return A - jnp.broadcast_to(jnp.eye(A.shape[-1], dtype=A.dtype), A.shape)


def _check(res, tol):
    bad = {k: float(v) for k, v in res.items() if not float(v) < tol}
    assert not bad, bad


# --------------------------------------------------------------------------------------
# conventions


@jax.jit
def _conventions(xi, eta, pts, g):
    w, v = xi[:, :3], xi[:, 3:]
    X, Y = lie.hat(xi), lie.hat(eta)
    wy, vy = eta[:, :3], eta[:, 3:]
    xh = jnp.concatenate([pts, jnp.ones_like(pts[:, :1])], -1)
    br = jnp.concatenate([jnp.cross(w, wy), jnp.cross(w, vy) - jnp.cross(wy, v)], -1)
    R, p = lie.se3_rotation(g), lie.se3_translation(g)
    Rw = jnp.einsum("nij,nj->ni", R, w)
    Ad_expected = jnp.concatenate([Rw, jnp.einsum("nij,nj->ni", R, v) + jnp.cross(p, Rw)], -1)
    return dict(
        vee_hat6=_maxabs(lie.vee(X) - xi),
        vee_hat3=_maxabs(lie.vee(lie.hat(w)) - w),
        hat3_cross=_maxabs(jnp.einsum("nij,nj->ni", lie.hat(w), pts) - jnp.cross(w, pts)),
        hat6_field=_maxabs(jnp.einsum("nij,nj->ni", X, xh)[:, :3] - (v + jnp.cross(w, pts))),
        hat6_bottom=_maxabs(X[:, 3, :]),
        hat_dispatch=_maxabs(lie.hat(xi) - lie.se3_hat(xi)) + _maxabs(lie.hat(w) - lie.so3_hat(w)),
        bracket_commutator=_maxabs(lie.hat(lie.bracket(xi, eta)) - (X @ Y - Y @ X)),
        bracket_formula=_maxabs(lie.bracket(xi, eta) - br),
        ad_matrix=_maxabs(jnp.einsum("nij,nj->ni", lie.ad(xi), eta) - br),
        coad_def=_maxabs(lie.coad(xi) + jnp.swapaxes(lie.ad(xi), -1, -2)),
        coad_action=_maxabs(lie.coad_action(xi, eta) - (lie.coad(xi) @ eta[..., None])[..., 0]),
        klein=_maxabs(lie.klein(xi, eta) - jnp.sum(w * vy + wy * v, -1)),
        bracket3=_maxabs(lie.bracket(w, wy) - jnp.cross(w, wy)) + _maxabs(lie.ad(w) - lie.hat(w)),
        Ad_formula=_maxabs(jnp.einsum("nij,nj->ni", lie.Ad(g), xi) - Ad_expected),
        coAd_def=_maxabs(lie.coAd(g) - jnp.swapaxes(lie.Ad(lie.se3_inv(g)), -1, -2)),
        Ad_so3=_maxabs(lie.Ad(R) - R) + _maxabs(lie.coAd(R) - R),
        from_Rp=_maxabs(lie.se3_from_rotation_translation(R, p) - g),
    )


def test_conventions(rng):
    xi, eta = rng.standard_normal((2, N, 6))
    g = _expm(_np_hat(rng.standard_normal((N, 6))))
    _check(_conventions(xi, eta, rng.standard_normal((N, 3)), g), 1e-14)
    with pytest.raises(ValueError):
        lie.hat(jnp.zeros(4))
    with pytest.raises(ValueError):
        lie.vee(jnp.zeros((2, 2)))
    for fn in (lie.exp, lie.dexp, lie.dexp_inv):
        with pytest.raises(ValueError):
            jax.eval_shape(fn, jax.ShapeDtypeStruct((5,), jnp.float64))
    with pytest.raises(ValueError):
        jax.eval_shape(lie.log, jax.ShapeDtypeStruct((2, 2), jnp.float64))


# --------------------------------------------------------------------------------------
# exp / log


@jax.jit
def _exp_log(xi):
    w = xi[:, :3]
    R = lie.so3_exp(w)
    g = lie.se3_exp(xi)
    res = dict(
        so3_orthogonal=_maxabs(_less_one(jnp.swapaxes(R, -1, -2) @ R)),
        so3_log_exp=_maxabs(lie.so3_log(R) - w),
        se3_log_exp=_maxabs(lie.se3_log(g) - xi),
        so3_exp_log=_maxabs(lie.so3_exp(lie.so3_log(R)) - R),
        se3_exp_log=_maxabs(lie.se3_exp(lie.se3_log(g)) - g),
        dispatch=_maxabs(lie.exp(xi) - g)
        + _maxabs(lie.exp(w) - R)
        + _maxabs(lie.log(R) - lie.so3_log(R))
        + _maxabs(lie.log(g) - lie.se3_log(g)),
    )
    return res, R, g


@pytest.mark.parametrize("theta", SPECIAL, ids=SPECIAL_IDS)
def test_exp_log(rng, theta):
    xi = _twists(rng, theta)
    res, R, g = _exp_log(xi)
    _check(res, 4e-15 * (1 + theta))
    # against the matrix exponential of the hat matrices
    np.testing.assert_allclose(R, _expm(_np_hat(xi[:, :3])), atol=2e-15 * (1 + theta))
    np.testing.assert_allclose(g, _expm(_np_hat(xi)), atol=1e-14)


@jax.jit
def _near_pi(w, R_half, g_half):
    R = lie.so3_exp(w)
    return lie.so3_log(R), lie.so3_exp(lie.so3_log(R)) - R, lie.so3_log(R_half), lie.se3_log(g_half)


def test_log_near_and_at_pi(rng):
    axes = _unit(rng, (N,))
    eps = np.array([1e-7, 1e-10, 0.0])[:, None, None]
    w = ((PI - eps) * axes).reshape(-1, 3)
    R_half = 2.0 * axes[:, :, None] * axes[:, None, :] - np.eye(3)  # exactly symmetric
    g_half = np.tile(np.eye(4), (N, 1, 1))
    g_half[:, :3, :3] = R_half
    g_half[:, :3, 3] = rng.standard_normal((N, 3))
    w_log, exp_log_err, w_half, xi_half = (np.asarray(a) for a in _near_pi(w, R_half, g_half))
    assert np.abs(exp_log_err).max() < 1e-15
    # accurate to rounding below π (not only up to the 1/sin θ amplification)
    assert np.abs(w_log - w)[: 2 * N].max() < 1e-12
    # exactly π: π n with the sign making the largest-|.| component positive
    np.testing.assert_allclose(np.linalg.norm(w_half, axis=-1), PI, rtol=1e-15)
    big = np.take_along_axis(w_half, np.argmax(np.abs(w_half), -1)[:, None], -1)
    assert np.all(big > 0)
    np.testing.assert_allclose(np.abs(np.sum(w_half * axes, -1)), PI, rtol=1e-15)
    np.testing.assert_allclose(_expm(_np_hat(w_half)), R_half, atol=1e-15)
    np.testing.assert_allclose(_expm(_np_hat(xi_half)), g_half, atol=1e-14)


@jax.jit
def _log_jacobians(w, v):
    """Jacobians of log∘exp and of log along R exp(δ) (tangent), to compare with dexp⁻¹."""
    logexp = lambda x: lie.so3_log(lie.so3_exp(x))
    R = lie.so3_exp(w)
    xi = jnp.concatenate([w, v])
    g = lie.se3_exp(xi)
    tangent = jax.jacfwd(lambda d: lie.so3_log(R @ lie.so3_exp(d)))(jnp.zeros(3))
    se3_tangent = jax.jacfwd(lambda d: lie.se3_log(g @ lie.se3_exp(d)))(jnp.zeros(6))
    return dict(
        so3_rev=_maxabs(jax.jacrev(logexp)(w) - jnp.eye(3)),
        so3_tangent=_maxabs(tangent - lie.so3_dexp_inv(w)),
        se3_tangent=_maxabs(se3_tangent - lie.se3_dexp_inv(xi)),
    )


@pytest.mark.parametrize("theta", SPECIAL + (PI - 1e-12,), ids=SPECIAL_IDS + ("pi-1e-12",))
def test_log_jacobian_is_inverse_of_exp_jacobian(rng, theta):
    # (at π − 1e-7 finite differences of log straddle π; compare with dexp⁻¹ instead)
    _check(_log_jacobians(theta * _unit(rng, ()), rng.standard_normal(3)), 2e-13)


# --------------------------------------------------------------------------------------
# group axioms


@jax.jit
def _axioms(xi, eta, X, Y, Z):
    g, h = lie.se3_exp(xi), lie.se3_exp(eta)
    gi = lie.se3_inv(g)
    mv = lambda A, x: jnp.einsum("nij,nj->ni", A, x)
    AdX, AdY = mv(lie.Ad(g), X), mv(lie.Ad(g), Y)
    br = lie.bracket
    w = Z  # a wrench
    dcoAd = jax.vmap(lambda y: jax.jvp(lambda t: lie.coAd(lie.se3_exp(t * y)), (0.0,), (1.0,))[1])(
        Y
    )
    res = dict(
        inv=_maxabs(_less_one(g @ gi)) + _maxabs(_less_one(gi @ g)),
        inv_is_exp_neg=_maxabs(gi - lie.se3_exp(-xi)),
        Ad_hom=_maxabs(lie.Ad(g @ h) - lie.Ad(g) @ lie.Ad(h)),
        Ad_inv=_maxabs(_less_one(lie.Ad(gi) @ lie.Ad(g))),
        Ad_hat=_maxabs(lie.hat(AdX) - g @ lie.hat(X) @ gi),
        Ad_ad=_maxabs(lie.Ad(g) @ lie.ad(X) @ lie.Ad(gi) - lie.ad(AdX)),
        Ad_bracket=_maxabs(mv(lie.Ad(g), br(X, Y)) - br(AdX, AdY)),
        jacobi=_maxabs(br(X, br(Y, Z)) + br(Y, br(Z, X)) + br(Z, br(X, Y))),
        antisym=_maxabs(br(X, Y) + br(Y, X)) + _maxabs(lie.ad(X) + lie.coad(X).mT),
        klein_Ad_invariant=_maxabs(lie.klein(AdX, AdY) - lie.klein(X, Y)),
        klein_ad_invariant=_maxabs(lie.klein(br(Z, X), Y) + lie.klein(X, br(Z, Y))),
        coAd_pairing=_maxabs(jnp.sum(mv(lie.coAd(g), w) * AdX, -1) - jnp.sum(w * X, -1)),
        coAd_hom=_maxabs(lie.coAd(g @ h) - lie.coAd(g) @ lie.coAd(h)),
        coad_pairing=_maxabs(jnp.sum(mv(lie.coad(Y), w) * X, -1) + jnp.sum(w * br(Y, X), -1)),
        coad_is_dcoAd=_maxabs(dcoAd - lie.coad(Y)),
    )
    return res, lie.Ad(g), lie.ad(xi)


@pytest.mark.parametrize("theta", SPECIAL, ids=SPECIAL_IDS)
def test_group_axioms(rng, theta):
    xi, eta = _twists(rng, theta), _twists(rng, theta)
    X, Y, Z = rng.standard_normal((3, N, 6))
    res, Ad_g, ad_xi = _axioms(xi, eta, X, Y, Z)
    _check(res, 5e-14)
    np.testing.assert_allclose(Ad_g, _expm(ad_xi), atol=1e-13)  # Ad(exp ξ) = expm(ad ξ)


# --------------------------------------------------------------------------------------
# dexp


def _series(A, terms=70):
    """Σ_{k≥0} (-A)^k/(k+1)! for a batch of square matrices."""
    eye = jnp.broadcast_to(jnp.eye(A.shape[-1], dtype=A.dtype), A.shape)

    def body(k, carry):
        term, total = carry
        term = -term @ A / (k + 2.0)
        return term, total + term

    return jax.lax.fori_loop(0, terms, body, (eye, eye))[1]


def _dexp_by_jvp(exp_fn, x, dx):
    """(exp(x)^{-1} d exp(x)[dx])^∨ — the definition of the left-trivialized dexp."""
    E, dE = jax.jvp(exp_fn, (x,), (dx,))
    Einv = jnp.swapaxes(E, -1, -2) if E.shape[-1] == 3 else lie.se3_inv(E)
    return lie.vee(Einv @ dE)


@jax.jit
def _dexp(xi, dxi):
    w, dw = xi[:, :3], dxi[:, :3]
    out = {}
    for name, x, dx, d, dinv, ex, adf in (
        ("so3", w, dw, lie.so3_dexp, lie.so3_dexp_inv, lie.so3_exp, lie.hat),
        ("se3", xi, dxi, lie.se3_dexp, lie.se3_dexp_inv, lie.se3_exp, lie.ad),
    ):
        D, Di = d(x), dinv(x)
        by_jvp = jax.vmap(functools.partial(_dexp_by_jvp, ex))(x, dx)
        out[name + "_def"] = _maxabs(jnp.einsum("nij,nj->ni", D, dx) - by_jvp)
        out[name + "_inv"] = _maxabs(_less_one(D @ Di)) + _maxabs(_less_one(Di @ D))
        out[name + "_series"] = _maxabs(D - _series(adf(x)))
        out[name + "_dispatch"] = _maxabs(lie.dexp(x) - D) + _maxabs(lie.dexp_inv(x) - Di)
    # left Jacobian J_l(w) = J_r(-w) = J_r(w)ᵀ, the V of se3_exp
    Jl = lie.so3_left_jacobian(w)
    out["left"] = (
        _maxabs(Jl - lie.so3_dexp(-w))
        + _maxabs(Jl - jnp.swapaxes(lie.so3_dexp(w), -1, -2))
        + _maxabs(_less_one(Jl @ lie.so3_left_jacobian_inv(w)))
        + _maxabs(jnp.einsum("nij,nj->ni", Jl, xi[:, 3:]) - lie.se3_exp(xi)[:, :3, 3])
    )
    # Runge–Kutta–Munthe-Kaas: g = g0 exp(Ω), ġ = g ξ̂  ⇔  Ω̇ = dexp⁻¹(Ω) ξ
    omega_dot = jnp.einsum("nij,nj->ni", lie.se3_dexp_inv(xi), dxi)
    g, gdot = jax.vmap(lambda o, od: jax.jvp(lie.se3_exp, (o,), (od,)))(xi, omega_dot)
    out["rkmk"] = _maxabs(lie.vee(lie.se3_inv(g) @ gdot) - dxi)
    return out


@pytest.mark.parametrize("theta", SPECIAL, ids=SPECIAL_IDS)
def test_dexp(rng, theta):
    _check(_dexp(_twists(rng, theta), rng.standard_normal((N, 6))), 2e-14)


@pytest.mark.parametrize("theta", SPECIAL, ids=SPECIAL_IDS)
def test_dexp_derivative_equals_autodiff_and_finite_differences(rng, theta):
    # The written-out derivative the ball joints' metric jet uses, at θ = 0 and across
    # the series/closed-form switch at θ = 1 included.
    w = jnp.asarray(_rotvecs(rng, np.full(N, theta)))
    got = so3_dexp_derivative(w)
    autodiff = jnp.moveaxis(jax.vmap(jax.jacfwd(lie.so3_dexp))(w), -1, 1)
    _check({"jacfwd": _maxabs(got - autodiff)}, 1e-14)
    h = 1e-6
    e = h * jnp.eye(3)[None]
    central = (lie.so3_dexp(w[:, None] + e) - lie.so3_dexp(w[:, None] - e)) / (2 * h)
    _check({"central differences": _maxabs(got - central)}, 1e-9)


@pytest.mark.parametrize("theta", SPECIAL, ids=SPECIAL_IDS)
def test_dexp_second_derivative_along_equals_autodiff_and_finite_differences(rng, theta):
    # The written-out second derivative the ball joints' metric jet differentiates with,
    # contracted with a direction u and with two vectors v per rotation (broadcast, as the
    # jet applies it to several velocities).
    w = jnp.asarray(_rotvecs(rng, np.full(N, theta)))
    u, v = jnp.asarray(rng.normal(size=(N, 3))), jnp.asarray(rng.normal(size=(2, N, 3)))
    got = so3_dexp_second_derivative_along(w, u, v)
    first = jax.vmap(jax.jacfwd(so3_dexp_derivative))(w)  # (N, l, 3, i, m)
    autodiff = jnp.einsum("nlaim,rni,nm->rnla", first, v, u)
    _check({"jacfwd": _maxabs(got - autodiff)}, 1e-14)
    h = 1e-6
    step = so3_dexp_derivative(w + h * u) - so3_dexp_derivative(w - h * u)
    central = jnp.einsum("nlai,rni->rnla", step, v) / (2 * h)
    _check({"central differences": _maxabs(got - central)}, 1e-9)


# --------------------------------------------------------------------------------------
# derivatives (jacfwd, jacrev vs central finite differences), zero, batching, dtypes


def _fd_jacobian(f, x, h=1e-6):
    """Central finite-difference Jacobian, shape f(x).shape + x.shape."""
    shape = x.shape
    n = x.size
    E = (h * jnp.eye(n, dtype=x.dtype)).reshape((n,) + shape)
    fpm = jax.vmap(f)(jnp.concatenate([x[None] + E, x[None] - E], 0))
    J = (fpm[:n] - fpm[n:]) / (2 * h)  # (n, *out)
    return jnp.moveaxis(J.reshape((n, -1)), 0, -1).reshape(f(x).shape + shape)


@functools.cache
def _probe(name):
    """All derivative and batching checks of one registered function, in ONE compilation.

    Returns numpy arrays: value (by vmap), jacfwd, jacrev, FD Jacobian (and the Hessian of
    ½|f|² for the core maps) at the registered points (the zero point last, if any), and f
    applied to the same points with batch dimensions (1, P), to compare with the vmap.
    """
    f, pts, thetas, zero = FUNCS[name]
    rng = np.random.default_rng(sorted(FUNCS).index(name))
    x = pts(rng, thetas)
    if zero is not None:
        x = np.concatenate([x, _zero_point(zero, x[0])[None]], 0)

    def one(y):
        out = dict(val=f(y), fwd=jax.jacfwd(f)(y), rev=jax.jacrev(f)(y), fd=_fd_jacobian(f, y))
        if name in WITH_HESSIAN:
            out["hess"] = jax.hessian(lambda z: 0.5 * jnp.sum(f(z) ** 2))(y)
        return out

    @jax.jit
    def run(x):
        out = jax.vmap(one)(x)
        out["batched"] = f(x[None])
        return out

    return {k: np.asarray(v) for k, v in run(x).items()}


def _pair(f):
    return lambda z: f(z[..., :6], z[..., 6:])


def _mat(fn, m):
    """Wrap a function of a m×m matrix as a function of its flattened entries."""
    return lambda z: fn(z.reshape(z.shape[:-1] + (m, m)))


def _flatten_outputs(fn):
    def f(z):
        out = fn(z)
        if isinstance(out, tuple):
            return jnp.concatenate([o[..., None] if o.ndim == z.ndim - 1 else o for o in out], -1)
        return out

    return f


def _col(thetas):
    return np.asarray(thetas, dtype=float)[:, None]


def _pts_w(rng, thetas):
    return _rotvecs(rng, thetas)


def _pts_xi(rng, thetas):
    return np.concatenate([_rotvecs(rng, thetas), rng.standard_normal((len(thetas), 3))], -1)


def _pts_R(rng, thetas):
    return _expm(_np_hat(_rotvecs(rng, thetas))).reshape(len(thetas), 9)


def _pts_g(rng, thetas):
    return _expm(_np_hat(_pts_xi(rng, thetas))).reshape(len(thetas), 16)


EXP_THETAS = (0.0, 1e-9, 0.05, 0.99, 1.3, 2.5, PI - 1e-7)  # FD well-posed for exp-type maps
LOG_THETAS = (0.0, 1e-9, 0.05, 0.99, 1.3, 2.5)  # π − 1e-7: test_log_jacobian_is_inverse_...
GENERIC = (0.7, 1.3, 2.2)


def _pts_vp(rng, thetas):
    return np.tan(0.5 * _col(thetas)) * _unit(rng, (len(thetas),))


def _pts_vp_rate(rng, thetas):
    return np.concatenate([_pts_vp(rng, thetas), rng.standard_normal((len(thetas), 3))], -1)


def _pts_quat(rng, thetas):
    th = _col(thetas)
    return np.concatenate([np.cos(th / 2), np.sin(th / 2) * _unit(rng, (len(thetas),))], -1)


def _pts_axis_angle(rng, thetas):
    return np.concatenate([_unit(rng, (len(thetas),)), _col(thetas)], -1)


def _pts_axis_angle_rate(rng, thetas):
    e = _unit(rng, (len(thetas),))
    edot = np.cross(e, rng.standard_normal(e.shape))
    return np.concatenate([e, _col(thetas), edot, rng.standard_normal((len(thetas), 1))], -1)


def _pts_uva(rng, thetas):
    n = len(thetas)
    return np.concatenate([_unit(rng, (n,)), _col(thetas), _unit(rng, (n,))], -1)


def _pts_uva_rate(rng, thetas):
    n = len(thetas)
    e = _unit(rng, (n,))
    edot = np.cross(e, rng.standard_normal(e.shape))
    return np.concatenate(
        [e, _col(thetas), edot, rng.standard_normal((n, 1)), _unit(rng, (n,))], -1
    )


def _pts_angles(rng, thetas):
    a = rng.uniform(-1.2, 1.2, (len(thetas), 3))
    a[:, 1] = np.asarray(thetas) * 0.5 + 0.2
    return a


def _pts_scalar(rng, thetas):
    return np.asarray(thetas, dtype=float)


def _pts_two(builder):
    return lambda rng, thetas: np.concatenate([builder(rng, thetas), builder(rng, thetas)], -1)


def _pts_Rp(rng, thetas):
    return np.concatenate([_pts_R(rng, thetas), rng.standard_normal((len(thetas), 3))], -1)


# name: (function of one flat array (batchable), point builder, thetas, zero point or None)
FUNCS = {
    "so3_hat": (lie.so3_hat, _pts_w, GENERIC, "zero"),
    "se3_hat": (lie.se3_hat, _pts_xi, GENERIC, "zero"),
    "so3_vee": (_mat(lie.so3_vee, 3), _pts_R, GENERIC, "identity3"),
    "se3_vee": (_mat(lie.se3_vee, 4), _pts_g, GENERIC, "identity4"),
    "so3_exp": (lie.so3_exp, _pts_w, EXP_THETAS, "zero"),
    "se3_exp": (lie.se3_exp, _pts_xi, EXP_THETAS, "zero"),
    "so3_log": (_mat(lie.so3_log, 3), _pts_R, LOG_THETAS, "identity3"),
    "se3_log": (_mat(lie.se3_log, 4), _pts_g, LOG_THETAS, "identity4"),
    "se3_inv": (_mat(lie.se3_inv, 4), _pts_g, EXP_THETAS, "identity4"),
    "Ad": (_mat(lie.Ad, 4), _pts_g, EXP_THETAS, "identity4"),
    "coAd": (_mat(lie.coAd, 4), _pts_g, EXP_THETAS, "identity4"),
    "ad": (lie.ad, _pts_xi, GENERIC, "zero"),
    "coad": (lie.coad, _pts_xi, GENERIC, "zero"),
    "bracket": (_pair(lie.bracket), _pts_two(_pts_xi), GENERIC, "zero"),
    "coad_action": (_pair(lie.coad_action), _pts_two(_pts_xi), GENERIC, "zero"),
    "klein": (_pair(lie.klein), _pts_two(_pts_xi), GENERIC, "zero"),
    "so3_dexp": (lie.so3_dexp, _pts_w, EXP_THETAS, "zero"),
    "so3_dexp_inv": (lie.so3_dexp_inv, _pts_w, EXP_THETAS, "zero"),
    "se3_dexp": (lie.se3_dexp, _pts_xi, EXP_THETAS, "zero"),
    "se3_dexp_inv": (lie.se3_dexp_inv, _pts_xi, EXP_THETAS, "zero"),
    "se3_from_rotation_translation": (
        lambda z: lie.se3_from_rotation_translation(
            z[..., :9].reshape(z.shape[:-1] + (3, 3)), z[..., 9:]
        ),
        _pts_Rp,
        GENERIC,
        "zero",
    ),
    # rotation parameterizations
    "rotation_from_vector_parameter": (
        lie.rotation_from_vector_parameter,
        _pts_vp,
        (0.0, 1e-9, 1.3, 2.5),
        "zero",
    ),
    "vector_parameter_from_rotation": (
        _mat(lie.vector_parameter_from_rotation, 3),
        _pts_R,
        (0.0, 1e-9, 1.3, 2.5),
        "identity3",
    ),
    "angular_velocity_from_vector_parameter": (
        lambda z: lie.angular_velocity_from_vector_parameter(z[..., :3], z[..., 3:]),
        _pts_vp_rate,
        (0.0, 1.3, 2.5),
        "zero",
    ),
    "rotation_from_quaternion": (lie.rotation_from_quaternion, _pts_quat, EXP_THETAS, "quat1"),
    "quaternion_from_rotation": (
        _mat(lie.quaternion_from_rotation, 3),
        _pts_R,
        (0.0, 1e-9, 1.3, 2.5, PI - 1e-3),
        "identity3",
    ),
    "rotation_vector_from_quaternion": (
        lie.rotation_vector_from_quaternion,
        _pts_quat,
        (0.0, 1e-9, 0.05, 1.3, 2.5),
        "quat1",
    ),
    "quaternion_from_rotation_vector": (
        lie.quaternion_from_rotation_vector,
        _pts_w,
        EXP_THETAS,
        "zero",
    ),
    "rotation_from_axis_angle": (
        lambda z: lie.rotation_from_axis_angle(z[..., :3], z[..., 3]),
        _pts_axis_angle,
        (0.0, 1e-9, 1.3, PI - 1e-7),
        "e3",
    ),
    "axis_angle_from_rotation": (
        _flatten_outputs(_mat(lie.axis_angle_from_rotation, 3)),
        _pts_R,
        (0.99, 1.3, 2.5),
        "identity3",
    ),
    "angular_velocity_from_axis_angle": (
        lambda z: lie.angular_velocity_from_axis_angle(
            z[..., :3], z[..., 3], z[..., 4:7], z[..., 7]
        ),
        _pts_axis_angle_rate,
        (0.0, 1.3, 2.5),
        "zero",
    ),
    "rotation_from_unit_vector_and_angle": (
        lambda z: lie.rotation_from_unit_vector_and_angle(z[..., :3], z[..., 3], z[..., 4:7]),
        _pts_uva,
        GENERIC,
        None,
    ),
    "unit_vector_and_angle_from_rotation": (
        _flatten_outputs(_mat(lambda R: lie.unit_vector_and_angle_from_rotation(R, _E[0]), 3)),
        _pts_R,
        GENERIC,
        None,
    ),
    "angular_velocity_from_unit_vector_and_angle": (
        lambda z: lie.angular_velocity_from_unit_vector_and_angle(
            z[..., :3], z[..., 3], z[..., 4:7], z[..., 7], z[..., 8:11]
        ),
        _pts_uva_rate,
        GENERIC,
        None,
    ),
    "rotation_from_euler_angles": (lie.rotation_from_euler_angles, _pts_angles, GENERIC, "zero"),
    "euler_angles_from_rotation": (
        _mat(lie.euler_angles_from_rotation, 3),
        _pts_R,
        GENERIC,
        None,
    ),
    "rotation_from_bryant_angles": (lie.rotation_from_bryant_angles, _pts_angles, GENERIC, "zero"),
    "bryant_angles_from_rotation": (
        _mat(lie.bryant_angles_from_rotation, 3),
        _pts_R,
        GENERIC,
        "identity3",
    ),
    "rotation_from_krylov_angles": (lie.rotation_from_krylov_angles, _pts_angles, GENERIC, "zero"),
    "krylov_angles_from_rotation": (
        _mat(lie.krylov_angles_from_rotation, 3),
        _pts_R,
        GENERIC,
        "identity3",
    ),
    "rotation_x": (lie.rotation_x, _pts_scalar, (0.0, 1.3), "zero"),
    "rotation_y": (lie.rotation_y, _pts_scalar, (0.0, 1.3), "zero"),
    "rotation_z": (lie.rotation_z, _pts_scalar, (0.0, 1.3), "zero"),
}


def _zero_point(kind, like):
    z = np.zeros_like(like)
    if kind == "identity3":
        return np.eye(3).reshape(9)
    if kind == "identity4":
        return np.eye(4).reshape(16)
    if kind == "quat1":
        z[0] = 1.0
    if kind == "e3":
        z[2] = 1.0
    return z


# at the identity the axis is undefined: finite values and derivatives, but not smooth
_NOT_SMOOTH_AT_ZERO = {"axis_angle_from_rotation"}
# functions whose second derivatives are checked too (finite everywhere, zero included)
WITH_HESSIAN = {"so3_exp"}
# aliases, checked for equality with what they dispatch to (test_conventions/exp_log/dexp)
ALIASES = {"hat", "vee", "exp", "log", "dexp", "dexp_inv", "se3_rotation", "se3_translation"}
ALIASES |= {"so3_left_jacobian", "so3_left_jacobian_inv"}
# thin wrappers of the quaternion maps (equality checked in test_rotation_parameterizations)
ALIASES |= {"rotation_from_euler_parameters", "euler_parameters_from_rotation"}


def test_registry_covers_public_api():
    missing = set(lie.__all__) - set(FUNCS) - ALIASES
    assert not missing, missing


@pytest.mark.parametrize("name", sorted(FUNCS))
def test_jacobians_vs_finite_differences(name):
    out = _probe(name)
    fwd, rev, fd = out["fwd"], out["rev"], out["fd"]
    if name in _NOT_SMOOTH_AT_ZERO:  # finiteness is checked in test_no_nan_at_exact_zero
        fwd, rev, fd = fwd[:-1], rev[:-1], fd[:-1]
    np.testing.assert_allclose(rev, fwd, atol=1e-13, rtol=1e-13)
    scale = max(1.0, float(np.abs(fwd).max()))
    np.testing.assert_allclose(fwd, fd, atol=1e-6 * scale, rtol=1e-6)


@pytest.mark.parametrize("name", sorted(n for n, v in FUNCS.items() if v[3] is not None))
def test_no_nan_at_exact_zero(name):
    out = _probe(name)  # the registered zero point is the last one
    for k in ("val", "fwd", "rev", "hess"):
        if k in out:
            assert np.all(np.isfinite(out[k][-1])), (k, "not finite at zero")


@pytest.mark.parametrize("name", sorted(FUNCS))
def test_batch_shapes_and_vmap(name):
    out = _probe(name)
    assert out["batched"].shape == (1,) + out["val"].shape
    np.testing.assert_allclose(out["batched"][0], out["val"], rtol=1e-14, atol=1e-14)


@pytest.mark.parametrize("name", sorted(FUNCS))
def test_dtype_follows_input(name):
    f, pts, thetas, _ = FUNCS[name]
    shape = pts(np.random.default_rng(0), thetas).shape
    for dtype in (jnp.float32, jnp.float64):
        out = jax.eval_shape(f, jax.ShapeDtypeStruct(shape, dtype))
        assert out.dtype == dtype, (dtype, out.dtype)


def test_batch_broadcasting():
    s = lambda *shape: jax.ShapeDtypeStruct(shape, jnp.float64)
    assert jax.eval_shape(lie.bracket, s(4, 1, 6), s(5, 6)).shape == (4, 5, 6)
    assert jax.eval_shape(lie.klein, s(4, 1, 6), s(5, 6)).shape == (4, 5)
    assert jax.eval_shape(lie.se3_from_rotation_translation, s(4, 1, 3, 3), s(5, 3)).shape == (
        4,
        5,
        4,
        4,
    )
    assert jax.eval_shape(lie.rotation_from_axis_angle, s(3), s(7)).shape == (7, 3, 3)
    assert jax.eval_shape(lie.rotation_from_euler_parameters, s(2), s(3)).shape == (2, 3, 3)
    for fn, shape, out in (
        (lie.hat, (2, 5, 6), (2, 5, 4, 4)),
        (lie.hat, (2, 5, 3), (2, 5, 3, 3)),
        (lie.vee, (2, 5, 4, 4), (2, 5, 6)),
        (lie.vee, (2, 5, 3, 3), (2, 5, 3)),
        (lie.se3_dexp_inv, (7, 6), (7, 6, 6)),
        (lie.exp, (2, 1, 6), (2, 1, 4, 4)),
        (lie.log, (3, 3), (3,)),
    ):
        assert jax.eval_shape(fn, s(*shape)).shape == out


@jax.jit
def _float32(w):
    R = lie.so3_exp(w)
    xi = jnp.concatenate([w, w[:, ::-1]], -1)
    return (
        R,
        lie.so3_log(R) - w,
        _less_one(lie.so3_dexp(w) @ lie.so3_dexp_inv(w)),
        lie.se3_log(lie.se3_exp(xi)) - xi,
    )


def test_float32_accuracy(rng):
    thetas = np.array([0.0, 1e-4, 0.05, 0.5, 0.999, 1.001, 2.0, 3.1])
    w = _rotvecs(rng, thetas).astype(np.float32)
    R, *errors = _float32(w)
    assert R.dtype == jnp.float32
    for err in errors:
        assert err.dtype == jnp.float32
        assert float(_maxabs(err)) < 2e-5


# --------------------------------------------------------------------------------------
# rotation parameterizations


@jax.jit
def _param_residuals(w, rate):
    """Round trips and agreement with so3_exp for a batch of rotation vectors w (|w| < π)."""
    R = lie.so3_exp(w)
    chi = jnp.linalg.norm(w, axis=-1)
    e = w / chi[:, None]
    c = jnp.tan(chi / 2)[:, None] * e
    q = jnp.concatenate([jnp.cos(chi / 2)[:, None], jnp.sin(chi / 2)[:, None] * e], -1)
    out = {}
    out["vp_forward"] = _maxabs(lie.rotation_from_vector_parameter(c) - R)
    out["vp_inverse"] = _maxabs(lie.vector_parameter_from_rotation(R) - c) / (
        1 + jnp.max(jnp.sum(c * c, -1))
    )
    out["axis_angle_forward"] = _maxabs(lie.rotation_from_axis_angle(e, chi) - R)
    e2, chi2 = lie.axis_angle_from_rotation(R)
    out["axis_angle_inverse"] = _maxabs(e2 - e) + _maxabs(chi2 - chi)
    out["quat_forward"] = _maxabs(lie.rotation_from_quaternion(q) - R)
    out["quat_inverse"] = _maxabs(lie.quaternion_from_rotation(R) - q)
    out["quat_unnormalized"] = _maxabs(lie.rotation_from_quaternion(-2.5 * q) - R)
    out["ep_forward"] = _maxabs(lie.rotation_from_euler_parameters(q[:, 0], q[:, 1:]) - R)
    q0, qv = lie.euler_parameters_from_rotation(R)
    out["ep_inverse"] = _maxabs(q0 - q[:, 0]) + _maxabs(qv - q[:, 1:])
    for name in ("euler", "bryant", "krylov"):
        ang = getattr(lie, f"{name}_angles_from_rotation")(R)
        R2 = getattr(lie, f"rotation_from_{name}_angles")(ang)
        out[name + "_round_trip"] = _maxabs(R2 - R)
        ang2 = getattr(lie, f"{name}_angles_from_rotation")(R2)
        out[name + "_angles_round_trip"] = _maxabs(ang2 - ang)
    for i in range(3):
        e3, phi = lie.unit_vector_and_angle_from_rotation(R, _E[i])
        out[f"uva{i}_round_trip"] = _maxabs(
            lie.rotation_from_unit_vector_and_angle(e3, phi, _E[i]) - R
        )
    # angular velocities against (Ṙ Rᵀ)^∨ by jax.jvp
    cdot = rate
    Rc, Rcdot = jax.jvp(lie.rotation_from_vector_parameter, (c,), (cdot,))
    spatial = lie.vee(Rcdot @ jnp.swapaxes(Rc, -1, -2))
    body = lie.vee(jnp.swapaxes(Rc, -1, -2) @ Rcdot)
    out["vp_omega_spatial"] = _maxabs(lie.angular_velocity_from_vector_parameter(c, cdot) - spatial)
    out["vp_omega_body"] = _maxabs(
        lie.angular_velocity_from_vector_parameter(c, cdot, body=True) - body
    )
    edot = jnp.cross(e, rate)
    chidot = rate[:, 0]
    Ra, Radot = jax.jvp(lie.rotation_from_axis_angle, (e, chi), (edot, chidot))
    out["eq40_omega"] = _maxabs(
        lie.angular_velocity_from_axis_angle(e, chi, edot, chidot)
        - lie.vee(Radot @ jnp.swapaxes(Ra, -1, -2))
    )
    a = jnp.array([0.3, -0.5, 0.8])  # a generic fixed vector
    e3, phi = lie.unit_vector_and_angle_from_rotation(R, a)
    e3dot = jnp.cross(e3, rate)
    phidot = rate[:, 1]
    f = lambda x, p: lie.rotation_from_unit_vector_and_angle(x, p, a)
    Ru, Rudot = jax.jvp(f, (e3, phi), (e3dot, phidot))
    out["eq42_omega"] = _maxabs(
        lie.angular_velocity_from_unit_vector_and_angle(e3, phi, e3dot, phidot, a)
        - lie.vee(Rudot @ jnp.swapaxes(Ru, -1, -2))
    )
    out["uva_generic_round_trip"] = _maxabs(Ru - R)
    # Euler angles are the seed's construction with a = e3: ψ from e1 to p, φ from p to e'1
    ang = lie.euler_angles_from_rotation(R)
    e3, phi = lie.unit_vector_and_angle_from_rotation(R, _E[2])
    out["euler_phi_is_seed_phi"] = _maxabs(jnp.cos(ang[:, 2] - phi) - 1.0)
    p = jnp.cross(_E[2], e3)
    p = p / jnp.linalg.norm(p, axis=-1, keepdims=True)
    out["euler_psi_is_node_angle"] = _maxabs(
        jnp.stack([jnp.cos(ang[:, 0]), jnp.sin(ang[:, 0])], -1) - p[:, :2]
    )
    return out


def test_rotation_parameterizations(rng):
    n = 64
    chi = rng.uniform(0.05, PI - 0.3, n)
    w = chi[:, None] * _unit(rng, (n,))
    _check(_param_residuals(w, rng.standard_normal((n, 3))), 2e-14)


@jax.jit
def _sequences(a, R):
    Rx, Ry, Rz = lie.rotation_x, lie.rotation_y, lie.rotation_z
    e = jnp.eye(3)
    ex = lambda i, t: lie.so3_exp(t[:, None] * e[i][None])
    res = dict(
        elementary=sum(_maxabs(Ri(a[:, 0]) - ex(i, a[:, 0])) for i, Ri in enumerate((Rx, Ry, Rz))),
        euler=_maxabs(
            lie.rotation_from_euler_angles(a) - ex(2, a[:, 0]) @ ex(0, a[:, 1]) @ ex(2, a[:, 2])
        ),
        bryant=_maxabs(
            lie.rotation_from_bryant_angles(a) - Rx(a[:, 0]) @ Ry(a[:, 1]) @ Rz(a[:, 2])
        ),
        krylov=_maxabs(
            lie.rotation_from_krylov_angles(a) - Ry(a[:, 0]) @ Rx(a[:, 1]) @ Rz(a[:, 2])
        ),
    )
    ranges = (
        lie.euler_angles_from_rotation(R),
        lie.bryant_angles_from_rotation(R),
        lie.krylov_angles_from_rotation(R),
    )
    return res, ranges


def test_angle_sequences_match_elementary_rotations(rng):
    a = rng.uniform(-1.4, 1.4, (N, 3))
    R = _expm(_np_hat(rng.standard_normal((N, 3))))
    res, (eu, br, kr) = _sequences(a, R)
    _check(res, 1e-15)
    # ranges: Euler θ ∈ [0, π]; Bryant β and Krylov θ ∈ [-π/2, π/2]; the others in (-π, π]
    assert np.all(eu[:, 1] >= 0) and np.all(eu[:, 1] <= PI)
    assert np.all(np.abs(br[:, 1]) <= PI / 2) and np.all(np.abs(kr[:, 1]) <= PI / 2)
    assert np.all(np.abs(np.concatenate([eu, br, kr])) <= PI)


@jax.jit
def _quat(w, R_exact_half):
    R = lie.so3_exp(w)
    q = lie.quaternion_from_rotation(R)
    qh = lie.quaternion_from_rotation(R_exact_half)
    return R, q, lie.rotation_from_quaternion(q), qh


def test_quaternion_all_pivots_and_sign(rng):
    # near the identity (pivot w) and near half-turns about each axis (pivots x, y, z)
    axes = np.eye(3) + 0.05 * rng.standard_normal((3, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    w = np.concatenate([0.1 * _unit(rng, (4,)), (PI - 1e-3) * axes, (PI - 1e-9) * -axes], 0)
    half = 2.0 * axes[:, :, None] * axes[:, None, :] - np.eye(3)
    R, q, Rq, qh = (np.asarray(a) for a in _quat(w, half))
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, rtol=1e-15)
    np.testing.assert_allclose(Rq, R, atol=1e-15)
    assert np.all(q[:, 0] >= 0)
    chi = np.linalg.norm(w, axis=-1, keepdims=True)
    expected = np.concatenate([np.cos(chi / 2), np.sin(chi / 2) * w / chi], -1)
    expected *= np.where(expected[:, :1] < 0, -1.0, 1.0)
    np.testing.assert_allclose(q, expected, atol=1e-15)
    # exact half-turns: w = 0 and the pivot (largest) component positive
    np.testing.assert_allclose(qh[:, 0], 0.0, atol=1e-16)
    np.testing.assert_allclose(qh[:, 1:], axes * np.sign(np.diag(axes))[:, None], atol=1e-15)
