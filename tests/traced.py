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
