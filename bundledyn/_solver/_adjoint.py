r"""`StoredStepsAdjoint`: reverse mode through a solve by one sweep over its accepted steps.

The forward solve is diffrax's own loop, not differentiated, which also records the
state at the start of every accepted step (an extra `SubSaveAt(steps=True)`) and, with
the Lie-group solvers, the field's values at the stages of the last steps
(`StageRecorder`), which the reverse pass replays instead of evaluating the field. The
reverse pass walks those steps from the last to the first and applies the VJP of the
solver's `step` alone: diffrax's controller, saving and event bookkeeping never enter
the reverse pass, and rejected steps leave nothing to undo. Each saved output adds its
cotangent where it came from: the step's end state, the step's dense output (saved
between steps) or, at an event located by a root find, the event's time and state
through the implicit function theorem.
"""

import functools as ft
from typing import Literal

import diffrax
import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.lax as lax
import jax.numpy as jnp
import jax.tree_util as jtu
from diffrax._adjoint import _inner_loop, _outer_loop
from diffrax._integrate import SaveState

from .._term import for_replay, for_reverse_mode, has_reverse_mode
from ._base import AbstractStageReplaySolver
from ._chart import body_term
from ._stage_record import StageRecorder, nbytes, slot_values, stage_values_shape, with_values

__all__ = ["StoredStepsAdjoint"]


def _is_subsaveat(x):
    return isinstance(x, diffrax.SubSaveAt)


def _is_save_state(x):
    return isinstance(x, SaveState)


def _zeros_like(tree):
    return jtu.tree_map(jnp.zeros_like, tree)


def _add(a, b):
    return jtu.tree_map(jnp.add, a, b)


_NOT_DIFFERENTIATED = (
    "`StoredStepsAdjoint` differentiates a solve with respect to `y0`, `args` and the "
    "terms' arrays only, and here one of `t0`, `t1`, `dt0`, `SaveAt(ts=...)` or a step-size "
    "controller's tolerances is differentiated too. For derivatives with respect to those, "
    "pass `adjoint=diffrax.RecursiveCheckpointAdjoint()`."
)


class StoredStepsAdjoint(diffrax.AbstractAdjoint):
    r"""Backpropagate through `diffrax.diffeqsolve` by storing the state at every accepted
    step and sweeping once backwards over those steps with the VJP of the solver's step.

    The gradients are those of `diffrax.RecursiveCheckpointAdjoint` (discretize, then
    differentiate: the same steps, the step sizes held fixed, events located by their root
    find differentiated implicitly). The reverse pass differentiates the solver's `step`
    only, not diffrax's loop around it (its step-size controller, saving and event checks),
    and each accepted step once, so the gradient compiles faster; it runs in about the
    checkpointed adjoint's time, which the VJP of the steps dominates (the figures are in
    `benchmarks/README.md`). `bundledyn.simulate` uses it with its Lie-group
    solvers.

    With an `AbstractStageReplaySolver` (the `AbstractRKMK` methods) and a term whose field
    has its own reverse pass (`AbstractSceneTerm.reverse_mode`: every scene's), the forward solve
    instead keeps the start states and the field's values at the stages of its last
    accepted steps, as many as fit in `stage_memory` bytes, and the start state of every
    block of that many steps (`StageRecorder`). The reverse sweep then steps with terms
    that give those values back (`ReplayedSceneTerm`) and evaluates no field, except at
    the steps that were not kept: it steps those again from their block's start, block by
    block, in the forward pass alone. It differentiates those steps' stages by their
    written-out reverse pass (`AbstractRKMK.stage_step` with `reverse_pass=True`), which
    evaluates the derivatives of the stages' exponentials and $\mathrm{dexp}^{-1}$ for all
    stages at once instead of stage by stage: autodiff differentiates them through dozens
    of scalar kernels per stage, so this shortens the gradient, least on short solves, where
    the costs that do not grow with the steps weigh more.

    Memory: one state per possible step, `max_steps` of them (with the replayed stages,
    one time per possible step, and the states as above). Past `max_memory` bytes, or
    where it does not apply (a solver with a state of its own, several event conditions,
    `max_steps=None`, stochastic terms), the solve is differentiated by `fallback`.

    Derivatives are taken with respect to `y0`, `args` and the terms' arrays (a scene's
    parameters); not with respect to `t0`, `t1`, `SaveAt(ts=...)`, tolerances or arrays
    inside an event's condition (differentiating the first four raises an error naming
    `diffrax.RecursiveCheckpointAdjoint`, which differentiates them). Reverse mode only
    (use `diffrax.ForwardMode` for forward mode).

    **Arguments:**

    - `max_memory`: the most bytes the stored states may take (default 1 GiB).
    - `stage_memory`: the most bytes the kept start states and stage values may take
      (default 2 MiB: 400 steps of `RKMK87` on gymnasium's humanoid; 0 keeps none). Under
      `vmap` each member keeps its own.
    - `fallback`: the adjoint used past the budget or where this one does not apply
      (default `diffrax.RecursiveCheckpointAdjoint()`, binomial checkpointing).
    - `field_reverse`: how each step's VJP passes through a scene's field:
      `"hand-derived"` (default), the field's own reverse pass (`ReverseModeSceneTerm`:
      written out for a floating base and a free shape in the Galilean frame, and for a
      prescribed base, elsewhere autodiff's VJP of the field), or `"autodiff"`, which
      transposes each step's stages, field included. The same gradients either way. The field's own
      pass needs only the field's inputs and outputs, so the reverse sweep replays the
      field's values (above) instead of evaluating the stages again; the gradient then
      takes less time than with `"autodiff"`.
    """

    max_memory: int = eqx.field(default=2**30, static=True)
    stage_memory: int = eqx.field(default=2**21, static=True)
    fallback: diffrax.AbstractAdjoint = diffrax.RecursiveCheckpointAdjoint()
    field_reverse: Literal["autodiff", "hand-derived"] = eqx.field(
        default="hand-derived", static=True
    )

    def __check_init__(self):
        if self.field_reverse not in ("autodiff", "hand-derived"):
            raise ValueError(
                "`StoredStepsAdjoint.field_reverse` must be 'autodiff' or 'hand-derived', "
                f"got {self.field_reverse!r}."
            )

    def applies(self, *, terms, solver, event, init_state, max_steps) -> bool:
        """Whether this solve is differentiated by stored steps (else by `fallback`)."""
        if max_steps is None or init_state.solver_state is not None:
            return False
        if any(
            isinstance(t, diffrax.AbstractBrownianPath)
            for t in jtu.tree_leaves(
                terms, is_leaf=lambda x: isinstance(x, diffrax.AbstractBrownianPath)
            )
        ):
            return False
        if event is not None and len(jtu.tree_leaves(event.cond_fn, is_leaf=callable)) != 1:
            return False
        return max_steps * nbytes(init_state.y) <= self.max_memory

    def _stage_capacity(self, terms, solver, init_state, args, max_steps) -> int:
        """How many steps' stage values the forward solve keeps (0: none, the reverse
        sweep evaluates every step's field again)."""
        term, _ = body_term(terms)
        if (
            self.field_reverse != "hand-derived"
            or not isinstance(solver, AbstractStageReplaySolver)
            or not has_reverse_mode(term)
        ):
            return 0
        values = stage_values_shape(solver, terms, init_state.tprev, init_state.y, args)
        per_step = nbytes(values) + nbytes(init_state.y)
        return min(self.stage_memory // per_step, max_steps)

    def loop(self, **kwargs):
        keys = ("terms", "solver", "event", "init_state", "max_steps")
        if not self.applies(**{k: kwargs[k] for k in keys}):
            return self.fallback.loop(**kwargs)
        args, terms, init_state = kwargs.pop("args"), kwargs.pop("terms"), kwargs["init_state"]
        for unused in ("passed_solver_state", "passed_controller_state", "throw"):
            del kwargs[unused]
        kwargs["init_state"] = eqx.tree_at(
            lambda s: (s.y, s.controller_state),
            init_state,
            (object(), lax.stop_gradient(init_state.controller_state)),
            is_leaf=lambda x: x is None,
        )
        kwargs = eqxi.nondifferentiable(kwargs, msg=_NOT_DIFFERENTIATED)
        final_state, aux_stats = _stored_steps_loop(
            (init_state.y, args, terms),
            loop=self._loop,
            field_reverse=self.field_reverse,
            capacity=self._stage_capacity(
                terms, kwargs["solver"], init_state, args, kwargs["max_steps"]
            ),
            **kwargs,
        )
        return _only_saves_differentiable(final_state), aux_stats


def _only_saves_differentiable(final_state):
    """Mark all but the saved times and values nondifferentiable (their cotangents would
    be dropped)."""

    def saves(s):
        states = jtu.tree_leaves(s.save_state, is_leaf=_is_save_state)
        return [x.ts for x in states] + [x.ys for x in states]

    kept = saves(final_state)
    final_state = eqxi.nondifferentiable_backward(final_state, symbolic=False)
    return eqx.tree_at(saves, final_state, kept)


def _time(t, y, args):
    del y, args
    return t


def _state(t, y, args):
    del t, args
    return y


def _record_state(init_state, max_steps, y):
    """An empty buffer for the steps' ends and `y` there, shaped as diffrax's own."""
    return SaveState(
        saveat_ts_index=0,
        ts=jnp.full(max_steps, jnp.inf, dtype=jnp.result_type(init_state.tprev)),
        ys=jtu.tree_map(
            lambda x: jnp.full((max_steps, *jnp.shape(x)), jnp.inf, jnp.result_type(x)), y
        ),
        save_index=0,
    )


def _forward(y__args__terms, *, loop, saveat, init_state, max_steps, record, capacity, **kwargs):
    """diffrax's loop, undifferentiated, with the steps' ends and end states recorded
    besides where `record` (reverse mode needs them; a solve that is not differentiated
    does not). With a `capacity`, the states are kept by `StageRecorder` instead, with the
    field's values at the last `capacity` steps' stages, and only the ends are recorded."""
    y, args, terms = y__args__terms
    init_state = eqx.tree_at(lambda s: s.y, init_state, y)
    if record:
        fn, like = (_time, init_state.tprev) if capacity else (_state, y)
        steps = diffrax.SubSaveAt(steps=True, fn=fn)
        saveat = eqx.tree_at(lambda s: s.subs, saveat, (saveat.subs, steps))
        init_state = eqx.tree_at(
            lambda s: s.save_state,
            init_state,
            (init_state.save_state, _record_state(init_state, max_steps, like)),
        )
    if record and capacity:
        checkpoints = -(-max_steps // capacity)
        kwargs["solver"] = StageRecorder(kwargs["solver"], capacity, checkpoints)
        recorder_state = kwargs["solver"].init(terms, init_state.tprev, init_state.tnext, y, args)
        init_state = eqx.tree_at(
            lambda s: s.solver_state, init_state, recorder_state, is_leaf=lambda x: x is None
        )
    final_state, aux_stats = loop(
        args=args,
        terms=terms,
        saveat=saveat,
        init_state=init_state,
        max_steps=max_steps,
        inner_while_loop=ft.partial(_inner_loop, kind="lax"),
        outer_while_loop=ft.partial(_outer_loop, kind="lax"),
        **kwargs,
    )
    if not record:
        return final_state, aux_stats, None, None
    user_saves, steps = final_state.save_state
    final_state = eqx.tree_at(lambda s: s.save_state, final_state, user_saves)
    if not capacity:
        return final_state, aux_stats, steps, None
    stages = final_state.solver_state
    final_state = eqx.tree_at(lambda s: s.solver_state, final_state, None)
    return final_state, aux_stats, steps, stages


@eqx.filter_custom_vjp
def _stored_steps_loop(y__args__terms, *, field_reverse, capacity, **kwargs):
    del field_reverse  # the reverse pass's choice
    final_state, aux_stats, _, _ = _forward(
        y__args__terms, record=False, capacity=capacity, **kwargs
    )
    return final_state, aux_stats


@_stored_steps_loop.def_fwd
def _stored_steps_loop_fwd(perturbed, y__args__terms, *, field_reverse, capacity, **kwargs):
    del perturbed, field_reverse
    final_state, aux_stats, steps, stages = _forward(
        y__args__terms, record=True, capacity=capacity, **kwargs
    )
    residuals = (steps, final_state, stages)
    return (final_state, aux_stats), residuals


class _Steps(eqx.Module):
    """The accepted steps, $[t_k, t_{k+1}]$ from $y_k$ for $k < n$, read off the record of
    their ends (indexed per step: nothing of the size of `max_steps` is formed)."""

    t0: jax.Array
    y0: object
    record: SaveState
    n: jax.Array
    t_last: jax.Array
    t_final: jax.Array
    event_inside: jax.Array

    def end(self, k):
        r"""$t_{k+1}$, and $+\infty$ past the last step. The record holds the steps' ends in
        order, except that with an event found by a root find diffrax replaces the last
        one by the event's time, so the last step's end is the loop's final time."""
        t = jnp.where(k < self.n - 1, self.record.ts[jnp.clip(k, 0, None)], self.t_last)
        return jnp.where(k < self.n, t, jnp.inf)

    def ends(self):
        return self.end(jnp.arange(self.record.ts.shape[0]))

    def start_time(self, k):
        """$t_k$."""
        return jnp.where(k == 0, self.t0, self.record.ts[jnp.maximum(k - 1, 0)])

    def start(self, k):
        """$(t_k, y_k)$, where the record holds the states."""
        previous = jnp.maximum(k - 1, 0)
        t = self.start_time(k)
        y = jtu.tree_map(
            lambda y0, ys: jnp.where(k == 0, y0, ys[previous]), self.y0, self.record.ys
        )
        return t, y


def _accepted_steps(record, final_state, t0, y0, event) -> _Steps:
    n = final_state.num_accepted_steps
    if event is not None and event.root_finder is not None:
        t_final = record.ts[jnp.maximum(record.save_index - 1, 0)]
        masks = [jnp.any(m) for m in jtu.tree_leaves(final_state.event_mask)]
        happened = jnp.any(jnp.stack(masks))
        event_inside = happened & (n > 0) & (t_final < final_state.tprev)
    else:
        t_final, event_inside = final_state.tprev, jnp.array(False)
    t0 = jnp.asarray(t0, record.ts.dtype)
    return _Steps(t0, y0, record, n, final_state.tprev, t_final, event_inside)


def _materialized(saves, grads):
    """The cotangents of each `SaveState`'s times and values, zeros where none came."""
    out = []
    for save, grad in zip(saves, grads, strict=True):
        g_ts = None if grad is None else grad.ts
        g_ys = None if grad is None else grad.ys
        g_ts = jnp.zeros_like(save.ts) if g_ts is None else g_ts
        g_ys = jtu.tree_map(
            lambda y, g: jnp.zeros_like(y) if g is None else g,
            save.ys,
            _zeros_like(save.ys) if g_ys is None else g_ys,
            is_leaf=lambda x: x is None,
        )
        out.append((g_ts, g_ys))
    return out


class _Entries(eqx.Module):
    r"""A `SubSaveAt`'s saved entries sorted into the steps they came from.

    `step[i]` is $-1$ for an entry saved at $t_0$, $k$ for one saved in step $k$
    ($t_k < \tau \le t_{k+1}$), and $n$ for an unused slot; `kind[i]` is 0 for a step's
    end, 1 for a point between a step's ends (dense output), 2 for an event's root.
    Entries are saved in time order, so each step's are the slice `lo[k]:hi[k]`.
    """

    times: jax.Array
    step: jax.Array
    kind: jax.Array

    def bounds(self, k):
        """The slice of the entries saved in step `k`."""
        return (
            jnp.searchsorted(self.step, k, side="left"),
            jnp.searchsorted(self.step, k, side="right"),
        )


def _sorted_entries(save, steps: _Steps, t0) -> _Entries:
    times = save.ts
    valid = jnp.arange(times.shape[0]) < save.save_index
    k = jnp.searchsorted(steps.ends(), times, side="left")
    k = jnp.where(valid, jnp.where(times == t0, -1, k), steps.n)
    root = steps.event_inside & (times == steps.t_final)
    kind = jnp.where(root, 2, jnp.where(times == steps.end(k), 0, 1))
    return _Entries(times, k, kind)


class _Problem(eqx.Module):
    """What the reverse sweep evaluates: the solver's step and the saved outputs, as
    functions of the differentiable parts of `args` and the terms."""

    solver: diffrax.AbstractSolver
    static_args: object
    static_terms: object
    event: diffrax.Event | None
    event_kwargs: dict
    field_reverse: str

    def step(self, y, diff_args, diff_terms, ta, tb, values=None):
        """The step from `y`; given its stage `values` (`StageRecorder`), with the field
        not evaluated but replayed (`ReplayedSceneTerm`)."""
        args = eqx.combine(diff_args, self.static_args)
        terms = eqx.combine(diff_terms, self.static_terms)
        if values is not None:
            assert isinstance(self.solver, AbstractStageReplaySolver)  # `_stage_capacity`

            def replayed(i):
                return for_replay(terms, jtu.tree_map(lambda v: v[i], values))

            y1, _, dense_info, _ = self.solver.stage_step(
                terms, ta, tb, y, args, stage_terms=replayed, reverse_pass=True
            )
            return y1, dense_info
        if self.field_reverse == "hand-derived":
            terms = for_reverse_mode(terms)
        y1, _, dense_info, _, _ = self.solver.step(terms, ta, tb, y, args, None, False)
        return y1, dense_info

    def stage_step(self, y, diff_args, diff_terms, ta, tb):
        """The step from `y` (the state it ends at) and the field's values at its stages."""
        args = eqx.combine(diff_args, self.static_args)
        terms = eqx.combine(diff_terms, self.static_terms)
        assert isinstance(self.solver, AbstractStageReplaySolver)  # `_stage_capacity`
        y1, _, _, values = self.solver.stage_step(terms, ta, tb, y, args)
        return y1, values

    def interpolate(self, dense_info, ta, tb, t):
        return self.solver.interpolation_cls(t0=ta, t1=tb, **dense_info).evaluate(t)

    def saved(self, fn, t, y, diff_args):
        return fn(t, y, eqx.combine(diff_args, self.static_args))

    def condition(self, dense_info, diff_args, diff_terms, ta, tb, t):
        assert self.event is not None  # only events found by a root find come here
        (cond_fn,) = jtu.tree_leaves(self.event.cond_fn, is_leaf=callable)
        return cond_fn(
            t=t,
            y=self.interpolate(dense_info, ta, tb, t),
            args=eqx.combine(diff_args, self.static_args),
            terms=eqx.combine(diff_terms, self.static_terms),
            solver=self.solver,
            **self.event_kwargs,
        )

    def at_root(self, fn, dense_info, diff_args, diff_terms, ta, tb, t):
        r"""The event's time and saved value, differentiable as the root $t^*$ of its
        condition $c$: $dt^* = -\partial c / \dot c$ (implicit function theorem), taken
        from one Newton correction whose value is held at the found root."""
        c = ft.partial(self.condition, dense_info, diff_args, diff_terms, ta, tb)
        value, slope = jax.jvp(c, (t,), (jnp.ones_like(t),))
        newton = t - value / lax.stop_gradient(slope)
        root = t + (newton - lax.stop_gradient(newton))
        return root, self.saved(fn, root, self.interpolate(dense_info, ta, tb, root), diff_args)


def _entry_cotangents(
    problem, fn, entries, g_ts, g_ys, y1, dense_info, diffs, ta, tb, k, real_event
):
    """Cotangents on the step's end state, its dense output, `args` and the terms from
    the entries saved in step `k`."""
    diff_args, diff_terms = diffs

    def at_end(i):
        _, vjp = jax.vjp(lambda y, a: problem.saved(fn, entries.times[i], y, a), y1, diff_args)
        ct_y, ct_a = vjp(jtu.tree_map(lambda g: g[i], g_ys))
        return ct_y, _zeros_like(dense_info), ct_a, _zeros_like(diff_terms)

    def between(i):
        def value(d, a):
            return problem.saved(
                fn, entries.times[i], problem.interpolate(d, ta, tb, entries.times[i]), a
            )

        _, vjp = jax.vjp(value, dense_info, diff_args)
        ct_d, ct_a = vjp(jtu.tree_map(lambda g: g[i], g_ys))
        return _zeros_like(y1), ct_d, ct_a, _zeros_like(diff_terms)

    def at_root(i):
        def value(d, a, tm):
            return problem.at_root(fn, d, a, tm, ta, tb, entries.times[i])

        _, vjp = jax.vjp(value, dense_info, diff_args, diff_terms)
        ct_d, ct_a, ct_t = vjp((g_ts[i], jtu.tree_map(lambda g: g[i], g_ys)))
        return _zeros_like(y1), ct_d, ct_a, ct_t

    branches = [at_end, between] + ([at_root] if real_event else [])

    def body(carry):
        i, total = carry
        kind = jnp.minimum(entries.kind[i], len(branches) - 1)
        return i + 1, _add(total, lax.switch(kind, branches, i))

    lo, hi = entries.bounds(k)
    zero = (
        _zeros_like(y1),
        _zeros_like(dense_info),
        _zeros_like(diff_args),
        _zeros_like(diff_terms),
    )
    _, total = lax.while_loop(lambda c: c[0] < hi, body, (lo, zero))
    return total


@_stored_steps_loop.def_bwd
def _stored_steps_loop_bwd(
    residuals,
    grad_out,
    perturbed,
    y__args__terms,
    *,
    loop,
    solver,
    saveat,
    event,
    t0,
    t1,
    dt0,
    stepsize_controller,
    max_steps,
    init_state,
    progress_meter,
    field_reverse,
    capacity,
):
    del loop, init_state, progress_meter
    record, final_state, stages = residuals
    grad_final_state, _ = grad_out
    y0, args, terms = y__args__terms
    # Only what is differentiated: a scene's numbers held constant are not transposed.
    _, args_perturbed, terms_perturbed = perturbed
    diff_args, static_args = eqx.partition(args, args_perturbed)
    diff_terms, static_terms = eqx.partition(terms, terms_perturbed)
    event_kwargs = dict(
        t0=t0,
        t1=t1,
        dt0=dt0,
        saveat=saveat,
        stepsize_controller=stepsize_controller,
        max_steps=max_steps,
    )
    problem = _Problem(solver, static_args, static_terms, event, event_kwargs, field_reverse)
    steps = _accepted_steps(record, final_state, t0, y0, event)

    subs = jtu.tree_leaves(saveat.subs, is_leaf=_is_subsaveat)
    saves = jtu.tree_leaves(final_state.save_state, is_leaf=_is_save_state)
    grads = jtu.tree_leaves(
        None if grad_final_state is None else grad_final_state.save_state,
        is_leaf=lambda x: x is None or _is_save_state(x),
    )
    grads = _materialized(saves, grads if len(grads) == len(saves) else [None] * len(saves))
    entries = [_sorted_entries(save, steps, t0) for save in saves]
    real_event = (
        event is not None
        and event.root_finder is not None
        and jnp.issubdtype(
            jax.eval_shape(
                problem.condition,
                *jax.eval_shape(problem.step, y0, diff_args, diff_terms, t0, t0)[1:],
                diff_args,
                diff_terms,
                t0,
                t0,
                t0,
            ).dtype,
            jnp.floating,
        )
    )

    def reverse_step(carry, kept=None):
        k, ct_y, ct_args, ct_terms = carry
        j = jnp.maximum(k, 0)  # members of a batch already done repeat step 0, discarded
        ta, tb = steps.start_time(j), steps.end(j)
        if kept is None:
            values, y_start = None, steps.start(j)[1]
        else:
            values, y_start = (slot_values(b, j, capacity) for b in (kept.values, kept.states))
        (y1, dense_info), vjp = jax.vjp(
            lambda y, a, tm: problem.step(y, a, tm, ta, tb, values),
            y_start,
            diff_args,
            diff_terms,
        )
        ct_y1, ct_dense = ct_y, _zeros_like(dense_info)
        for sub, (g_ts, g_ys), e in zip(subs, grads, entries, strict=True):
            d_y1, d_dense, d_args, d_terms = _entry_cotangents(
                problem,
                sub.fn,
                e,
                g_ts,
                g_ys,
                y1,
                dense_info,
                (diff_args, diff_terms),
                ta,
                tb,
                j,
                real_event,
            )
            ct_y1, ct_dense = _add(ct_y1, d_y1), _add(ct_dense, d_dense)
            ct_args, ct_terms = _add(ct_args, d_args), _add(ct_terms, d_terms)
        ct_y0, d_args, d_terms = vjp((ct_y1, ct_dense))
        return k - 1, ct_y0, _add(ct_args, d_args), _add(ct_terms, d_terms)

    carry = (steps.n - 1, _zeros_like(y0), _zeros_like(diff_args), _zeros_like(diff_terms))
    if stages is None:
        carry = lax.while_loop(lambda c: c[0] >= 0, reverse_step, carry)
    else:

        def stepped(i, y):
            ta, tb = steps.start_time(i), steps.end(i)
            return problem.stage_step(y, diff_args, diff_terms, ta, tb)

        carry = _replayed_sweep(reverse_step, stepped, carry, stages, steps.n, capacity)
    _, ct_y0, ct_args, ct_terms = carry
    for sub, (_, g_ys), e in zip(subs, grads, entries, strict=True):
        d_y0, d_args = _initial_cotangents(problem, sub.fn, e, g_ys, y0, diff_args, t0)
        ct_y0, ct_args = _add(ct_y0, d_y0), _add(ct_args, d_args)
    return ct_y0, ct_args, ct_terms


def _replayed_sweep(reverse_step, stepped, carry, kept, n, capacity):
    r"""The reverse sweep over steps $n - 1, \dots, 0$ by `reverse_step` given what is kept
    for each (`Kept`), in blocks of `capacity` steps ($[c\,m, (c + 1)\,m)$, last first).

    The forward solve kept the last `capacity` steps' start states and stage values, and
    the start state of every block. Before a block is swept, its steps that were not kept
    are stepped again from the block's start (`stepped(i, y)`: step $i$ from $y$, giving
    the state it ends at and the field's values at its stages, in the forward pass alone)
    into the slots of the steps already swept. A solve of at most `capacity` steps is one
    block and evaluates no field. Every loop runs its own number of times, so under `vmap`
    no member evaluates what it does not need.
    """

    def block(state):
        c, kept, carry = state
        lo = jnp.maximum(c * capacity, 0)
        unkept = jnp.minimum((c + 1) * capacity, n - capacity)

        def refill(state):
            i, y, kept = state
            y1, values = stepped(i, y)
            values = with_values(kept.values, i, capacity, values)
            states = with_values(kept.states, i, capacity, y)
            return i + 1, y1, eqx.tree_at(lambda k: (k.values, k.states), kept, (values, states))

        start = jtu.tree_map(lambda b: b[jnp.maximum(c, 0)], kept.checkpoints)
        _, _, kept = lax.while_loop(lambda s: s[0] < unkept, refill, (lo, start, kept))
        carry = lax.while_loop(
            lambda carry: (carry[0] >= lo) & (carry[0] >= 0),
            lambda carry: reverse_step(carry, kept),
            carry,
        )
        return c - 1, kept, carry

    last = jnp.floor_divide(n - 1, capacity)
    _, _, carry = lax.while_loop(lambda s: s[0] >= 0, block, (last, kept, carry))
    return carry


def _initial_cotangents(problem, fn, entries, g_ys, y0, diff_args, t0):
    """Cotangents on $y_0$ and `args` from the entries saved at $t_0$."""

    def body(carry):
        i, total = carry
        _, vjp = jax.vjp(lambda y, a: problem.saved(fn, t0, y, a), y0, diff_args)
        return i + 1, _add(total, vjp(jtu.tree_map(lambda g: g[i], g_ys)))

    count = jnp.sum(entries.step == -1)
    _, total = lax.while_loop(
        lambda c: c[0] < count, body, (0, (_zeros_like(y0), _zeros_like(diff_args)))
    )
    return total
