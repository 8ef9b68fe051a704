"""One member's gradients, timed in alternation with its forward solve.

Over the member's predictable horizon (`measure.predictable_horizon`), with bundledyn's
default solver at rtol `RTOL` (atol = rtol / 100) and its default step control:

1. `jax.grad` of a loss on the rollout (`_rollouts.rollout_loss`: the squared final base
   position and shape, as a function of the initial base twist) over the loss itself (the
   forward solve), for each of `adjoints()`; an adjoint that fails to trace, compile or
   run, or gives a non-finite gradient, is recorded with its error and no time;
2. the VJP of the body field the RKMK stages evaluate (`bd.SceneTerm.body_vf`) over the
   field, and the VJP of one `RKMK87` step (at the forward solve's mean step) over the
   step, both as the default adjoint takes them, each in a compiled loop (`speed.gradient.gradient_units`, as part 5c of the speed
   benchmark measures them on the chain).
"""

import time

import diffrax
import jax
import jax.numpy as jnp

from benchmarks._rollouts import rollout_loss
from benchmarks._timing import blocking, interleaved
from benchmarks.speed.gradient import gradient_units

RTOL = 1e-8
DEFAULT = "default"  # the key of `simulate`'s default adjoint (`adjoint=None`)
LIMITS = {"grad": 4.0, "vjp": 3.0}  # gradient / forward solve; stage and step VJP / primal


def default_solver_name() -> str:
    """The solver `bd.simulate` integrates with when given none."""
    from bundledyn._simulate import DEFAULT_SOLVER

    return DEFAULT_SOLVER.__name__


def default_adjoint_name() -> str:
    """The class `bd.simulate(..., adjoint=None)` differentiates its default solver with."""
    from bundledyn._simulate import DEFAULT_SOLVER, default_adjoint

    return type(default_adjoint(DEFAULT_SOLVER())).__name__


def adjoints() -> dict:
    """The adjoints compared: `simulate`'s default (None, with the field's written-out
    reverse pass), the same with autodiff's, and diffrax's checkpointed
    discretise-then-optimise and its continuous backsolve."""
    import bundledyn as bd

    return {
        DEFAULT: None,
        "StoredStepsAdjoint, autodiff field": bd.StoredStepsAdjoint(field_reverse="autodiff"),
        "RecursiveCheckpointAdjoint": diffrax.RecursiveCheckpointAdjoint(),
        "BacksolveAdjoint": diffrax.BacksolveAdjoint(),
    }


def loss_options(rtol=RTOL, **options):
    """`bd.simulate`'s keywords for the loss: its default solver at `rtol`."""
    return {"rtol": rtol, "atol": rtol * 1e-2, **options}


def checked_sampler(fn, *args):
    """`(sampler, first call s, None)` of `fn(*args)` after one call that compiles and
    runs it, or `(None, None, error)` where that call raises or returns a non-finite
    value."""
    start = time.perf_counter()
    try:
        out = jax.block_until_ready(fn(*args))
    except Exception as error:  # noqa: BLE001 - any failure of an adjoint is reported
        return None, None, f"{type(error).__name__}: {str(error).strip()[:200]}"
    seconds = time.perf_counter() - start
    if not all(bool(jnp.all(jnp.isfinite(x))) for x in jax.tree.leaves(out)):
        return None, None, "non-finite gradient"
    return blocking(fn, *args), seconds, None


def measure_gradient(scene, state, t1, repeats, rtol=RTOL):
    """One member's gradients over `t1` (module docstring): times, compile seconds and the
    ratios `"<adjoint>"` (gradient / forward), `"field_vjp"` and `"step_vjp"` (None for an
    adjoint that failed)."""
    forward = jax.jit(rollout_loss(scene, state, t1, **loss_options(rtol)))
    samplers, compiles, errors = {"forward": blocking(forward, state.xi)}, {}, {}
    for name, adjoint in adjoints().items():
        loss = rollout_loss(scene, state, t1, **loss_options(rtol, adjoint=adjoint))
        sampler, compiles[name], errors[name] = checked_sampler(jax.jit(jax.grad(loss)), state.xi)
        if sampler is not None:
            samplers[name] = sampler
    units, profile = gradient_units(scene, state, t1, rtol)
    timed = {name: stats for name, (_, stats) in interleaved(samplers | units, repeats).items()}
    forward_time = timed["forward"]["median"]
    results = {
        name: {"error": errors[name]}
        if errors[name]
        else {"grad": timed[name], "compile": max(compiles[name] - timed[name]["median"], 0.0)}
        for name in errors
    }
    ratios = {
        name: timed[name]["median"] / forward_time if name in timed else None for name in errors
    }
    ratios |= {
        f"{unit}_vjp": timed[f"{unit}_vjp"]["median"] / timed[unit]["median"]
        for unit in ("field", "step")
    }
    return {
        "steps": profile["steps"],
        "stages": profile["stages"],
        "forward": timed["forward"],
        "adjoints": results,
        "units": {unit: timed[unit] for unit in units},
        "ratios": ratios,
    }


def gradient_header(packages, repeats, horizons, rtol=RTOL):
    """What the gradient part records once: its provenance and environment (it may be
    measured apart from the rest, `--only gradient`), its repeats and settings."""
    from benchmarks._provenance import environment, provenance

    return {
        "provenance": provenance(),
        "environment": environment(packages),
        "repeats": repeats,
        "horizons": list(horizons),
        "rtol": rtol,
        "atol": rtol * 1e-2,
        "solver": default_solver_name(),
        "default_adjoint": default_adjoint_name(),
        "adjoints": list(adjoints()),
    }


def gradient_member(member, seed, known, *, horizons, repeats):
    """`member`'s entry with its gradients under "gradient" (None where no horizon is
    predictable): `known`, its entry measured before (if any), gives its horizon, else
    it is found here."""
    from benchmarks.family.measure import describe, member_start, predictable_horizon

    scene, model, state = member_start(member, seed)
    if known is not None and "horizon" in known:
        entry = dict(known)
    else:
        t1, _, agreement = predictable_horizon(scene, state, horizons)
        entry = describe(member, model, t1, agreement)
    t1 = entry["horizon"]
    entry["gradient"] = None if t1 is None else measure_gradient(scene, state, t1, repeats)
    return entry
