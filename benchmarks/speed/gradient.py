"""Part 5: the gradient of the 10 s rollout against its forward solve (5a), with baselines
of diffrax's own adjoint loop; its peak memory over 10⁵ steps (5b); and where its time
goes (5c)."""

import functools as ft
import resource
import time

import bundledyn as bd
from benchmarks._models import chain_scene, initial_state
from benchmarks._rollouts import rollout_loss
from benchmarks._timing import blocking, interleaved, loop_sampler
from benchmarks.speed.config import BASELINE_DEPTHS, LOOP_EVALS, simulate_options


def default_adjoint_name():
    """The adjoint `bd.simulate` differentiates RKMK87's solves with when given none."""
    from bundledyn._simulate import default_adjoint

    return type(default_adjoint(bd.RKMK87())).__name__


def gradient_cost(repeats, t1, rtol=1e-6):
    """Part 5a: `jax.grad` of a loss on the rollout over the forward solve, with
    `simulate`'s default adjoint and with diffrax's `RecursiveCheckpointAdjoint`, timed in
    alternation with the units of `gradient_units` and the baselines."""
    import diffrax
    import jax

    scene = chain_scene(5)
    s = initial_state(scene)
    options = simulate_options("RKMK87", "adaptive", rtol)
    loss = rollout_loss(scene, s, t1, **options)
    checkpointed = rollout_loss(
        scene, s, t1, adjoint=diffrax.RecursiveCheckpointAdjoint(), **options
    )
    units, profile = gradient_units(scene, s, t1, rtol)
    baselines = baseline_samplers(t1, rtol)
    samplers = {
        "forward": blocking(jax.jit(loss), s.xi),
        "grad": blocking(jax.jit(jax.grad(loss)), s.xi),
        "grad_checkpointed": blocking(jax.jit(jax.grad(checkpointed)), s.xi),
    }
    timings = interleaved(samplers | units | baselines, repeats)
    (_, forward), (first, grad) = timings["forward"], timings["grad"]
    return {
        "adjoint": default_adjoint_name(),
        "forward": forward,
        "grad": grad,
        "grad_checkpointed": timings["grad_checkpointed"][1],
        "grad_compile": max(first - grad["median"], 0.0),
        "ratio": grad["median"] / forward["median"],
        "baselines": {
            str(depth): {
                unit: timings[f"baseline_{depth}_{unit}"][1]
                for unit in ("forward", "grad", "field", "field_vjp")
            }
            for depth in BASELINE_DEPTHS
        },
        "profile": profile | {k: timings[k][1] for k in units},
    }


def skew_network_ode(depth, dim=30):
    """Part 5a's baselines: the field $f(y) = K_L\\tanh(K_{L-1}\\cdots\\tanh(K_1 y))$ of
    `depth` $= L$ fixed skew-symmetric `dim`×`dim` matrices (as many numbers as the
    5-body chain's state), linear for $L = 1$, and an initial state. Its VJP costs little
    more than the field: what diffrax's adjoint loop costs with a field of a given price and
    an inexpensive reverse pass. Returns `(field, y0)`, `field(t, y, args)`."""
    import jax.numpy as jnp
    import numpy as np

    rng = np.random.default_rng(0)
    K = rng.normal(size=(depth, dim, dim)) / np.sqrt(dim)
    K = jnp.asarray(K - np.swapaxes(K, 1, 2))

    def field(t, y, args):
        for k in K[:-1]:
            y = jnp.tanh(k @ y)
        return K[-1] @ y

    return field, jnp.asarray(rng.normal(size=dim))


def baseline_loss(field, t1, rtol):
    """A loss on diffrax's own `Dopri8` solving `field` over `t1` at `rtol`
    (`RecursiveCheckpointAdjoint`, diffrax's default): $|y(t_1)|^2$."""
    import diffrax
    import jax.numpy as jnp

    term = diffrax.ODETerm(field)
    controller = diffrax.PIDController(rtol=rtol, atol=rtol)

    def loss(y0):
        sol = diffrax.diffeqsolve(
            term, diffrax.Dopri8(), 0.0, t1, 0.1, y0, stepsize_controller=controller
        )
        return jnp.sum(sol.ys[-1] ** 2)

    return loss


def baseline_samplers(t1, rtol):
    """Part 5a's baselines (`skew_network_ode`, depths `BASELINE_DEPTHS`): their forward
    solve, its `jax.grad`, and the field and its VJP in compiled loops."""
    import jax

    samplers = {}
    for depth in BASELINE_DEPTHS:
        field, y0 = skew_network_ode(depth)
        loss = baseline_loss(field, t1, rtol)
        samplers |= {
            f"baseline_{depth}_forward": blocking(jax.jit(loss), y0),
            f"baseline_{depth}_grad": blocking(jax.jit(jax.grad(loss)), y0),
            f"baseline_{depth}_field": loop_sampler(
                lambda i, y, f=field: f(0.0, y, None), y0, LOOP_EVALS
            ),
            f"baseline_{depth}_field_vjp": loop_sampler(
                vjp_unit(lambda i, y, f=field: f(0.0, y, None)), y0, LOOP_EVALS
            ),
        }
    return samplers


def vjp_unit(fn):
    """The VJP of a loop unit `fn(i, y)` at `y`, pulling back `y` itself (shaped as `y`)."""
    import jax

    return lambda i, y: jax.vjp(lambda y: fn(i, y), y)[1](y)[0]


def replayed_field_vjp_sampler(scene, state, calls=LOOP_EVALS):
    """A sampler of seconds per VJP of `scene`'s body field at `state` as `simulate`'s
    default adjoint takes it (`loop_sampler`): the field's values kept, its own reverse pass
    (`ReplayedSceneTerm`: written out where it applies, else autodiff's)."""
    from bundledyn._term import for_replay

    term = bd.SceneTerm(scene)
    y = term.encode(0.0, state)

    def field(i, y, term):  # the twist as a 4×4 matrix, so that the loop can feed it back
        xi, xdot = term.body_vf(0.0, y, None)
        return bd.lie.se3_hat(xi), xdot

    replayed = for_replay(term, term.body_vf(0.0, y, None))
    return loop_sampler(vjp_unit(ft.partial(field, term=replayed)), y, calls)


def gradient_units(scene, state, t1, rtol):
    """Part 5c: samplers of where the gradient's time goes, per call in compiled loops
    (`loop_sampler`): the body field the RKMK stages evaluate (`bd.SceneTerm.body_vf`), one
    `RKMK87` step at the forward solve's mean step, and their VJPs as `simulate`'s default
    adjoint takes them: where the field's written-out reverse pass covers the scene, with
    the field's values kept by the forward solve (`ReplayedSceneTerm`, so the field's VJP
    is that pass alone), otherwise by autodiff; with the solve's steps (accepted and
    rejected)."""
    import jax

    from bundledyn._term import for_replay

    options = simulate_options("RKMK87", "adaptive", rtol)
    steps = int(bd.simulate(scene, state, t1, **options).stats["num_steps"])
    term, solver = bd.SceneTerm(scene), bd.RKMK87(dense_output=False)
    y = term.encode(0.0, state)
    h = t1 / steps
    field_values = term.body_vf(0.0, y, None)
    stage_values = solver.stage_step(term, 0.0, h, y, None)[3]

    def field(i, y, term=term):  # the twist as a 4×4 matrix, so that the loop can feed it back
        xi, xdot = term.body_vf(0.0, y, None)
        return bd.lie.se3_hat(xi), xdot

    def step(i, y):
        return solver.step(term, 0.0, h, y, None, None, False)[0]

    def replayed_step(i, y):
        def stage_terms(k):
            return for_replay(term, jax.tree.map(lambda v: v[k], stage_values))

        return solver.stage_step(term, 0.0, h, y, None, stage_terms=stage_terms, reverse_pass=True)[
            0
        ]

    units = {
        "field": field,
        "field_vjp": vjp_unit(ft.partial(field, term=for_replay(term, field_values))),
        "step": step,
        "step_vjp": vjp_unit(replayed_step),
    }
    calls = {"field": LOOP_EVALS, "step": LOOP_EVALS // 10}
    samplers = {k: loop_sampler(fn, y, calls[k.split("_")[0]]) for k, fn in units.items()}
    return samplers, {
        "steps": steps,
        "stages": solver.tableau.step_stages,
        "field_unit": "body field (`SceneTerm.body_vf`); VJPs as `simulate`'s default adjoint",
    }


def gradient_memory(steps):
    """Part 5b (own process): peak memory of `jax.grad` through a `steps`-step rollout,
    differentiated by `simulate`'s default adjoint."""
    import jax
    import jax.numpy as jnp

    scene = chain_scene(5)
    s = initial_state(scene)
    dt = 1e-4
    loss = rollout_loss(
        scene,
        s,
        steps * dt,
        dt0=dt,
        solver=bd.RKMK4(),
        max_steps=steps,
    )
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    compiled = jax.jit(jax.grad(loss)).lower(s.xi).compile()
    analysis = compiled.memory_analysis()
    start = time.perf_counter()
    grad = jax.block_until_ready(compiled(s.xi))
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return {
        "steps": steps,
        "adjoint": default_adjoint_name(),
        "xla_temp_bytes": getattr(analysis, "temp_size_in_bytes", None),
        "peak_rss_bytes": peak,
        "rss_before_bytes": before,
        "seconds": seconds,
        "grad_finite": bool(jnp.all(jnp.isfinite(grad))),
    }
