"""XLA's CPU settings for small, deep graphs: opt-in, like float64."""

import os
import warnings

from jaxlib.version import __version_info__ as _JAXLIB_VERSION

# Each flag with the last jaxlib `(major, minor)` whose XLA knows it (None: all so far).
# XLA aborts the whole process on a flag it does not know (`Unknown flag in XLA_FLAGS`), so
# a removed flag must not be passed: jaxlib 0.11 removed the switch back to the older CPU
# emitters (0.11.2 aborts on it, seen 2026-11-22; 0.10.2 accepts it).
_FLAGS = {
    "--xla_cpu_use_fusion_emitters=false": (0, 10),
    "--xla_cpu_multi_thread_eigen=false": None,
    "--xla_cpu_enable_concurrency_optimized_scheduler=false": None,
}


def _cpu_xla_flags(jaxlib_version: tuple[int, ...]) -> tuple[str, ...]:
    """bundledyn's XLA CPU flags that a jaxlib of this `(major, minor, …)` version knows."""
    release = tuple(jaxlib_version[:2])
    return tuple(flag for flag, last in _FLAGS.items() if last is None or release <= last)


CPU_XLA_FLAGS = _cpu_xla_flags(_JAXLIB_VERSION)


def use_cpu_xla_flags() -> bool:
    """Add bundledyn's XLA CPU flags to `XLA_FLAGS`, before JAX starts its backend.

    - `--xla_cpu_use_fusion_emitters=false`: XLA's CPU fusion emitters compile the small,
      deep graphs of kinematic trees more slowly (XLA's part of compiling `jax.grad` of a
      20-body rollout: 19.6 s with XLA's defaults, 14.8 s with these flags).
    - `--xla_cpu_multi_thread_eigen=false`: the 6×6 and $d\\times d$ products of one
      vector field are far too small to share between threads.
    - `--xla_cpu_enable_concurrency_optimized_scheduler=false`: XLA's default schedule
      lets its runtime run the field's ~100 tiny kernels on several threads, and handing a
      kernel to another core costs more than running it, so timings turn bimodal. Five
      alternating processes each on 2 cores: a 20-body field 38.5–39.4 µs with the flag,
      38.7–69.5 µs without (three runs of five at 64–70); 1024 vmapped 5-body rollouts
      552–607 against 442–570 per second; compile times unchanged. (A shared machine's
      slow phases remain either way, pinned to one core too.)

    The first flag is left out with jaxlib 0.11 and later, whose XLA no longer has it and
    would abort on it; `CPU_XLA_FLAGS` holds the flags for the installed jaxlib.

    Measured together against XLA's defaults (`benchmarks/results/speed.md`), across the
    runs of 2026-11-22: one vector field 1.2–2.7× faster (1 to 20 bodies), 1024 vmapped
    rollouts 2.5–2.8× faster.

    A flag already present in `XLA_FLAGS` (either value) is left as the user set it. XLA
    reads the variable once, when the first computation starts the backend; called later,
    this changes nothing and warns.

    **Returns:**

    `True` if the flags will take effect, `False` if the backend had already started.
    """
    from jax._src import xla_bridge

    if xla_bridge.backends_are_initialized():
        warnings.warn(
            "bundledyn.use_cpu_xla_flags() was called after JAX started its backend, so XLA "
            "will not read the flags; call it before the first JAX computation, or set "
            f"XLA_FLAGS='{' '.join(CPU_XLA_FLAGS)}' in the environment.",
            stacklevel=2,
        )
        return False
    flags = os.environ.get("XLA_FLAGS", "").split()
    names = {flag.split("=")[0] for flag in flags}
    flags += [flag for flag in CPU_XLA_FLAGS if flag.split("=")[0] not in names]
    os.environ["XLA_FLAGS"] = " ".join(flags)
    return True
