"""Timing shared by the benchmarks.

Every time is a summary of repeated runs, `{"median", "min", "max"}` in seconds. Times
that are compared with each other are taken in alternation (`interleaved`), so that on a
shared machine both sides of a ratio see the same slow and fast phases. Functions run in
compiled loops (`loop_sampler`) are timed per call without dispatch, and programs whose
XLA flags matter run in worker processes (`run_worker`): XLA reads its flags when the
backend starts.
"""

import json
import os
import statistics
import subprocess
import sys
import time

from benchmarks._output import ROOT


def summary(samples):
    """`{"median", "min", "max"}` of `samples`."""
    return {"median": statistics.median(samples), "min": min(samples), "max": max(samples)}


def timed(fn, *args, repeats):
    """`(output, compile s, summary of run s)`; compile = first call minus the median run."""
    import jax

    start = time.perf_counter()
    out = jax.block_until_ready(fn(*args))
    first = time.perf_counter() - start
    runs = []
    for _ in range(repeats):
        start = time.perf_counter()
        out = jax.block_until_ready(fn(*args))
        runs.append(time.perf_counter() - start)
    return out, max(first - statistics.median(runs), 0.0), summary(runs)


def interleaved(samplers, repeats):
    """Time zero-argument callables in alternation: `{name: (first call s, summary of runs)}`.

    Each of `repeats` rounds calls every sampler once, in reverse order every other round.
    A sampler returns its own measurement in seconds (per unit of work), or None to be
    timed here.
    """

    def sample(fn):
        start = time.perf_counter()
        seconds = fn()
        return time.perf_counter() - start if seconds is None else seconds

    first = {name: sample(fn) for name, fn in samplers.items()}
    runs = {name: [] for name in samplers}
    names = list(samplers)
    for r in range(repeats):
        for name in names if r % 2 == 0 else names[::-1]:
            runs[name].append(sample(samplers[name]))
    return {name: (first[name], summary(runs[name])) for name in names}


def blocking(fn, *args):
    """A sampler of `fn(*args)` that waits for JAX's result."""
    import jax

    def sample():
        jax.block_until_ready(fn(*args))

    return sample


def loop_sampler(fn, y, calls):
    """A sampler of seconds per call of `fn(i, y)` (a pytree shaped as `y`) inside a
    compiled `fori_loop`, each call depending on the last (no dispatch)."""
    import jax

    def body(i, y):
        return jax.tree.map(lambda a, b: a + 1e-6 * b, y, fn(i, y))

    run = blocking(jax.jit(lambda y: jax.lax.fori_loop(0, calls, body, y)), y)

    def sample():
        start = time.perf_counter()
        run()
        return (time.perf_counter() - start) / calls

    return sample


def compile_seconds(jitted, *args):
    """Seconds to trace and lower `jitted` at `args`, to compile it with XLA, and both."""
    start = time.perf_counter()
    lowered = jitted.lower(*args)
    traced = time.perf_counter() - start
    lowered.compile()
    return {
        "trace_and_lower": traced,
        "xla": time.perf_counter() - start - traced,
        "total": time.perf_counter() - start,
    }


def run_worker(module, mode, args, flags):
    """`python -m module --mode *args` in a fresh process with `XLA_FLAGS` = `flags`: the
    JSON it prints last."""
    env = dict(os.environ, XLA_FLAGS=" ".join(flags))
    command = [sys.executable, "-m", module, f"--{mode}", *args]
    done = subprocess.run(command, env=env, cwd=ROOT, stdout=subprocess.PIPE, check=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])
