"""`simulate`: integrate a scene from an initial state with diffrax."""

import dataclasses
import functools
import inspect

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu
import numpy as np

from . import lie
from ._precision import (
    check_tolerances,
    default_tolerance,
    tolerance_refusal,
    tolerance_refusals,
)
from ._scene import Scene
from ._solver._adjoint import StoredStepsAdjoint
from ._solver._base import AbstractLieGroupSolver
from ._solver._rkmk import RKMK87, AbstractRKMK
from ._solver._starting_step import starting_step
from ._state import State
from ._stiffness import out_of_steps_advice
from ._term import SceneTerm
from ._trajectory import Trajectory
from ._validation import concrete

# The solver `simulate` integrates with when given none (benchmarks read it from here).
DEFAULT_SOLVER = RKMK87


@jax.custom_jvp
def _polar_factor(A):
    """The orthogonal polar factor $UV^T$ of $A = USV^T$ (batched over leading axes)."""
    u, _, vt = jnp.linalg.svd(A)
    return u @ vt


@_polar_factor.defjvp
def _polar_factor_jvp(primals, tangents):
    # A = PH with H symmetric positive definite, so P^T dA = Ω H + dH with Ω = P^T dP skew,
    # and P^T dA - dA^T P = ΩH + HΩ = hat((tr H - H) ω) for Ω = hat(ω). tr H - H has the
    # eigenvalues s_i + s_j > 0. Autodiff of the SVD divides by s_i^2 - s_j^2 instead, zero
    # at every rotation; this rule calls no SVD derivative, so it differentiates again.
    (A,), (dA,) = primals, tangents
    P = _polar_factor(A)
    Pt = jnp.swapaxes(P, -1, -2)
    H = Pt @ A
    K = Pt @ dA
    trace = jnp.trace(H, axis1=-2, axis2=-1)[..., None, None]
    omega = jnp.linalg.solve(
        trace * jnp.broadcast_to(jnp.eye(3, dtype=H.dtype), H.shape)
        - (H + jnp.swapaxes(H, -1, -2)) / 2,
        lie.so3_vee(K - jnp.swapaxes(K, -1, -2))[..., None],
    )
    return P, P @ lie.so3_hat(omega[..., 0])


def project_to_se3(g):
    """The nearest pose: the rotation block replaced by its polar factor $UV^T$ (SVD).

    Differentiable everywhere the block is invertible, rotations included, where the
    singular values coincide (`jax.grad` of the SVD alone is NaN there).

    **Arguments:**

    - `g`: 4×4 matrices, shape `(..., 4, 4)`, whose rotation block is near SO(3).

    **Returns:**

    Poses in SE(3) with the same translation and bottom row `[0, 0, 0, 1]`.
    """
    return (
        g.at[..., :3, :3]
        .set(_polar_factor(g[..., :3, :3]))
        .at[..., 3, :]
        .set(jnp.array([0.0, 0.0, 0.0, 1.0]))
    )


def _orthogonality_error(g):
    R = g[..., :3, :3]
    identity = jnp.broadcast_to(jnp.eye(3, dtype=R.dtype), R.shape)
    return jnp.max(jnp.abs(jnp.swapaxes(R, -1, -2) @ R - identity))


def _interpolates(saveat: diffrax.SaveAt, event) -> bool:
    """Whether the solve evaluates the solver's dense output (saving between steps, events)."""
    subs = jtu.tree_leaves(saveat.subs, is_leaf=lambda s: isinstance(s, diffrax.SubSaveAt))
    return saveat.dense or event is not None or any(s.ts is not None for s in subs)


def _checked_when_run(t0, t1, controller, dtype):
    """`t1`, with the checks a traced solve needs made when it runs (inside `jax.jit` the
    numbers cannot be checked in Python): finite times and, for an adaptive `controller`,
    tolerances a step size can meet. On `t1` alone, so the solve's arithmetic is unchanged."""
    refusal = jnp.where(jnp.isfinite(t0) & jnp.isfinite(t1), 0, 1)
    messages = ("simulate: `t0` and `t1` must be finite.",)
    if controller is not None:
        tolerance = tolerance_refusal(controller.rtol, controller.atol, dtype)
        refusal = jnp.where(refusal == 0, jnp.where(tolerance > 0, tolerance + 1, 0), refusal)
        messages += tolerance_refusals(dtype)
    return eqx.branched_error_if(t1, refusal > 0, jnp.maximum(refusal - 1, 0), messages)


def default_adjoint(solver) -> diffrax.AbstractAdjoint:
    """The adjoint `simulate` differentiates `solver`'s solves with when given none."""
    if isinstance(solver, AbstractLieGroupSolver):
        return StoredStepsAdjoint()
    return diffrax.RecursiveCheckpointAdjoint()


# `simulate`'s arguments that are numbers: data of the compiled solve, not keys of its cache.
_NUMBERS = ("t1", "t0", "rtol", "atol", "dt0")


def _numbers_as_data(function):
    """`function` compiled by `equinox.filter_jit`, and called with its `_NUMBERS` as weakly
    typed JAX scalars after checking the caller's values (`filter_jit` holds Python numbers
    static: each new horizon or tolerance compiled the whole solve again). A decorator, so
    that the documentation reads `function`'s own signature and docstring."""
    solve, signature = eqx.filter_jit(function), inspect.signature(function)

    @functools.wraps(function)
    def simulate(*args, **kwargs):
        bound = signature.bind(*args, **kwargs)
        bound.apply_defaults()
        given = bound.arguments
        for name in ("rtol", "atol"):
            if given[name] is None:
                given[name] = default_tolerance(given["state0"].g.dtype)
        if given["stepsize_controller"] is None and _adaptive(given["solver"]):
            # Here, not in the compiled solve, where the numbers arrive traced.
            check_tolerances(given["rtol"], given["atol"], given["state0"].g.dtype)
        for name in ("t0", "t1"):
            value = concrete(given[name])
            if value is not None and not np.all(np.isfinite(value)):
                raise ValueError(f"simulate: `{name}` must be finite, got {given[name]}.")
        given.update({name: _traced(given[name]) for name in _NUMBERS})
        try:
            return solve(*bound.args, **bound.kwargs)
        except eqx.EquinoxRuntimeError as error:
            if _OUT_OF_STEPS not in str(error):
                raise
            advice = out_of_steps_advice(
                given["scene"], given["state0"], given["t0"], given["t1"], given["max_steps"]
            )
            raise eqx.EquinoxRuntimeError(f"{_OUT_OF_STEPS} {advice}".rstrip()) from error

    return simulate


# diffrax's message when a solve runs out of `max_steps`.
_OUT_OF_STEPS = diffrax.RESULTS[diffrax.RESULTS.max_steps_reached]


def _adaptive(solver) -> bool:
    """Whether `solver` (None: the default) takes steps of the size its error calls for."""
    return solver is None or isinstance(solver, diffrax.AbstractAdaptiveSolver)


def _traced(x):
    """A Python number as a weakly typed JAX scalar (it promotes as the number would)."""
    if isinstance(x, int | float) and not isinstance(x, bool):
        x64 = bool(jax.config.read("jax_enable_x64"))
        return _scalar(float(x), x64)  # an integer time is a time
    return x


@functools.lru_cache(maxsize=256)
def _scalar(x: float, x64: bool) -> jax.Array:
    """`jnp.asarray(x)`, made once per value and precision (a JAX array is immutable); a
    concrete array even when first asked for while a function is being traced."""
    with jax.ensure_compile_time_eval():
        return jnp.asarray(x)


@_numbers_as_data
def simulate(
    scene: Scene,
    state0: State,
    t1,
    *,
    t0: float | jax.Array = 0.0,
    solver=None,
    rtol: float | None = None,
    atol: float | None = None,
    dt0=None,
    stepsize_controller: diffrax.AbstractStepSizeController | None = None,
    saveat: diffrax.SaveAt | None = None,
    adjoint: diffrax.AbstractAdjoint | None = None,
    event: diffrax.Event | None = None,
    max_steps: int | None = 16384,
    progress: bool = False,
    throw: bool = True,
) -> Trajectory:
    """Integrate Chevallier's equations (2.6)–(2.7) of `scene` from `state0` at `t0` to `t1`.

    **Arguments:**

    - `scene`: the `Scene` (system, effects, shape mode, frame).
    - `state0`: the initial `State` (for a `Prescribed` shape, q and qdot are taken from its
      motion). The state and the system's parameters are checked at run time
      (`State.checked`, `AbstractSystem.checked`): a NaN, a pose off SE(3), a negative
      mass or a non-physical inertia raises, inside `jax.jit` and `jax.grad` too.
    - `t1`, `t0`: end and start times. These, `rtol`, `atol` and `dt0` are data of the
      compiled solve: a new value, a Python number included, does not compile it again.
    - `solver`: a Lie-group solver (an `AbstractLieGroupSolver`: `RKMK87` default, `RKMK54`,
      `RKMK4`, `LieEuler`, `VariationalMidpoint`) or any diffrax solver, which then integrates the pose in its
      4×4 embedding: there its rotation drifts off SO(3) by the solver's error, so the saved
      poses are projected back (`project_to_se3`) and the drift before projection is
      reported as `stats["embedding_drift"]`.
    - `rtol`, `atol`: tolerances of the default step-size controller (adaptive solvers),
      by default 1e-8, or 1000 rounding errors of the state's dtype where that is larger
      (1.2e-4 in float32); a `diffrax.PIDController` with Gustafsson's PI coefficients
      (`pcoeff=0.4`, `icoeff=0.3`); unused when `stepsize_controller` is given. Negative tolerances, and
      tolerances below the working precision's rounding error, raise `ValueError` (no step
      size meets them), or, traced inside `jax.jit`, stop the solve with equinox's runtime
      error; ones within 100 times it warn. A `t0` or `t1` that is not finite is refused
      the same two ways.
    - `dt0`: the initial step; required by fixed-step solvers, where it is the step. For
      adaptive ones it defaults to Hairer, Nørsett & Wanner's starting step (two field
      evaluations before the stepping loop, which add one copy of the field to the
      compiled program), not the 0.01 that diffrax 0.7 starts every solve with; pass
      `dt0` to skip them.
    - `stepsize_controller`: a diffrax step-size controller in place of the default: the PI
      controller above for adaptive solvers, `diffrax.ConstantStepSize()` for fixed-step
      ones. With `diffrax.ConstantStepSize()` and `dt0`, an adaptive solver takes fixed
      steps: a `vmap`ped batch then takes the same steps in every member, where adaptive
      members run in lockstep until the one needing most steps is done. An adaptive
      controller given without `dt0` starts at the step described under `dt0`, from its
      own `rtol` and `atol`.
    - `saveat`: a `diffrax.SaveAt`; default saves at `t0` and `t1`. When it saves only
      at `t0`, `t1` or the steps and there is no `event`, a Lie-group solver skips the
      stages that only its dense output uses (`AbstractRKMK`'s `dense_output`): `RKMK87`
      then evaluates the field 13 times per step instead of 14.
    - `adjoint`: how reverse mode differentiates the solve: a diffrax adjoint. Default
      `StoredStepsAdjoint` for the Lie-group solvers (one reverse sweep over the accepted
      steps), `diffrax.RecursiveCheckpointAdjoint` for any other solver. Derivatives with
      respect to `t0`, `t1`, `saveat`'s times or the tolerances need
      `diffrax.RecursiveCheckpointAdjoint()` (the default refuses them, saying so).
    - `event`: an optional `diffrax.Event` to stop at.
    - `max_steps`: step budget; running out raises (or, with `throw=False`, sets `result`),
      naming the stiffest mode at `state0` and the steps an explicit solver needs for it.
    - `progress`: show diffrax's text progress meter.

    **Returns:**

    A `Trajectory`.
    """
    solver = DEFAULT_SOLVER() if solver is None else solver
    saveat = diffrax.SaveAt(t0=True, t1=True) if saveat is None else saveat
    if isinstance(solver, AbstractRKMK) and not _interpolates(saveat, event):
        solver = dataclasses.replace(solver, dense_output=False)
    # Parameters may be traced (fitted, or under `jax.grad`): check them once per solve.
    scene = eqx.tree_at(lambda s: s.system, scene, scene.system.checked())
    term = SceneTerm(scene)
    y0 = term.encode(t0, state0.checked())
    if stepsize_controller is not None:
        controller = stepsize_controller
    elif isinstance(solver, diffrax.AbstractAdaptiveSolver):
        # Gustafsson's PI controller (Hairer & Wanner, Solving ODEs II, §IV.2; diffrax's
        # docstring lists it): diffrax's default I controller rejects far more of RKMK87's
        # long steps.
        controller = diffrax.PIDController(
            rtol=default_tolerance(y0[0].dtype) if rtol is None else rtol,
            atol=default_tolerance(y0[0].dtype) if atol is None else atol,
            pcoeff=0.4,
            icoeff=0.3,
        )
    else:
        controller = diffrax.ConstantStepSize()
    adaptive = isinstance(controller, diffrax.AbstractAdaptiveStepSizeController)
    if adaptive:
        check_tolerances(controller.rtol, controller.atol, y0[0].dtype)
    t1 = _checked_when_run(t0, t1, controller if adaptive else None, y0[0].dtype)
    if dt0 is None and adaptive and isinstance(solver, diffrax.AbstractAdaptiveSolver):
        h = starting_step(
            term,
            t0,
            y0,
            None,
            error_order=solver.error_order(term),
            rtol=controller.rtol,
            atol=controller.atol,
        )
        dt0 = jnp.where(t1 >= t0, h, -h)
    elif dt0 is None and isinstance(controller, diffrax.ConstantStepSize):
        raise ValueError(
            f"{type(solver).__name__} with {type(controller).__name__} takes fixed steps: "
            "pass `dt0`."
        )
    sol = diffrax.diffeqsolve(
        term,
        solver,
        t0,
        t1,
        dt0,
        y0,
        saveat=saveat,
        stepsize_controller=controller,
        adjoint=default_adjoint(solver) if adjoint is None else adjoint,
        event=event,
        max_steps=max_steps,
        progress_meter=diffrax.TextProgressMeter() if progress else diffrax.NoProgressMeter(),
        throw=throw,
    )
    if sol.ts is None or sol.ys is None:
        raise ValueError(
            "`saveat` must save states (`t0`, `t1`, `ts` or `steps`), not only `dense`."
        )
    g, x = sol.ys
    stats = dict(sol.stats)
    if not isinstance(solver, AbstractLieGroupSolver):
        stats["embedding_drift"] = _orthogonality_error(g)
        g = project_to_se3(g)
    states, U = jax.vmap(term.decode_with_locked_velocity)(sol.ts, (g, x))
    return Trajectory(
        sol.ts, states.g, states.q, states.xi, states.qdot, U, stats, sol.result, scene
    )
