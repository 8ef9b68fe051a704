"""XLA's CPU settings for small, deep graphs: opt-in, like float64."""

import os
import warnings

from jaxlib.version import __version_info__ as _JAXLIB_VERSION

# Each flag with the jaxlib releases whose XLA knows it, `[since, until)` as `(major, minor,
# patch)` (None: no bound). XLA aborts the whole process on a flag it does not know
# (`Unknown flag in XLA_FLAGS`), so a flag must be passed to those releases only: jaxlib 0.11
# removed the switch back to the older CPU emitters, and the YNNPACK switch first appears
# in 0.8.1.
_FLAGS = {
    "--xla_cpu_use_fusion_emitters=false": (None, (0, 11, 0)),
    "--xla_cpu_multi_thread_eigen=false": (None, None),
    "--xla_cpu_enable_concurrency_optimized_scheduler=false": (None, None),
    "--xla_cpu_experimental_ynn_fusion_type=": ((0, 8, 1), None),
}


def _cpu_xla_flags(jaxlib_version: tuple[int, ...]) -> tuple[str, ...]:
    """bundledyn's XLA CPU flags that a jaxlib of this `(major, minor, patch)` version knows."""
    release = tuple(jaxlib_version[:3])
    return tuple(
        flag
        for flag, (since, until) in _FLAGS.items()
        if (since is None or release >= since) and (until is None or release < until)
    )


CPU_XLA_FLAGS = _cpu_xla_flags(_JAXLIB_VERSION)
"""The XLA CPU flags `use_cpu_xla_flags` adds, those the installed jaxlib knows."""


def use_cpu_xla_flags() -> bool:
    r"""Add bundledyn's XLA CPU flags to `XLA_FLAGS`, before JAX starts its backend.

    bundledyn's programs are many tiny kernels (products of 3×3 to 6×6 matrices), for
    which XLA's CPU defaults, made for large arrays, cost more than the work:

    - `--xla_cpu_use_fusion_emitters=false`: the fusion emitters compile the small, deep
      graphs of kinematic trees more slowly.
    - `--xla_cpu_multi_thread_eigen=false`: the products of one vector field are far too
      small to share between threads.
    - `--xla_cpu_enable_concurrency_optimized_scheduler=false`: handing a tiny kernel to
      another core costs more than running it, and makes timings bimodal.
    - `--xla_cpu_experimental_ynn_fusion_type=` (empty: no YNNPACK fusions): the default
      hands small products to YNNPACK calls whose overhead exceeds their work.

    The first flag is left out with jaxlib 0.11 and later, whose XLA no longer has it and
    would abort on it, and the last with jaxlib 0.8.0 and earlier, whose XLA does not have
    it yet; `CPU_XLA_FLAGS` holds the flags for the installed jaxlib. What they gain is
    measured in `benchmarks/` (`benchmarks/README.md`).

    A flag already present in `XLA_FLAGS` (either value) is left as the user set it. XLA
    reads the variable once, when the first computation starts the backend; called later,
    this changes nothing, and warns unless `XLA_FLAGS` already names every flag (called
    again, as the command line does inside a program that called it first).

    **Returns:**

    `True` if the flags will take effect, `False` if the backend had already started.
    """
    from jax._src import xla_bridge

    flags = os.environ.get("XLA_FLAGS", "").split()
    names = {flag.split("=")[0] for flag in flags}
    missing = [flag for flag in CPU_XLA_FLAGS if flag.split("=")[0] not in names]
    if xla_bridge.backends_are_initialized():
        if not missing:
            return False
        warnings.warn(
            "bundledyn.use_cpu_xla_flags() was called after JAX started its backend, so XLA "
            "will not read the flags; call it before the first JAX computation, or set "
            f"XLA_FLAGS='{' '.join(CPU_XLA_FLAGS)}' in the environment.",
            stacklevel=2,
        )
        return False
    os.environ["XLA_FLAGS"] = " ".join(flags + missing)
    return True
