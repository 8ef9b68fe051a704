"""Inspecting traced programs."""

import jax


def scan_lengths(fn, *args):
    """Lengths of every `lax.scan` in the traced program of `fn(*args)`, nested ones included."""

    def walk(jaxpr):
        for eqn in jaxpr.eqns:
            if eqn.primitive.name == "scan":
                yield eqn.params["length"]
            for param in eqn.params.values():
                for sub in param if isinstance(param, tuple | list) else (param,):
                    if isinstance(sub, jax.extend.core.ClosedJaxpr):
                        yield from walk(sub.jaxpr)
                    elif isinstance(sub, jax.extend.core.Jaxpr):
                        yield from walk(sub)

    return set(walk(jax.make_jaxpr(fn)(*args).jaxpr))


_LOWERINGS = [0]
jax.monitoring.register_event_duration_secs_listener(
    lambda event, duration, **kwargs: _LOWERINGS.__setitem__(
        0, _LOWERINGS[0] + (event == "/jax/core/compile/jaxpr_to_mlir_module_duration")
    )
)


def lowerings(fn, *args):
    """`(fn(*args), how many programs JAX lowered to XLA for it)`: op-by-op evaluation lowers
    one program per primitive, a compiled function one (none once cached)."""
    before = _LOWERINGS[0]
    out = jax.block_until_ready(fn(*args))
    return out, _LOWERINGS[0] - before
