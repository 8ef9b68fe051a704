"""XLA's CPU settings for small, deep graphs: opt-in, like float64."""

import os
import warnings

from jaxlib.version import __version_info__ as _JAXLIB_VERSION

# Each flag with the jaxlib releases whose XLA knows it, `[since, until)` as `(major, minor,
# patch)` (None: no bound). XLA aborts the whole process on a flag it does not know
# (`Unknown flag in XLA_FLAGS`), so a flag must be passed to those releases only: jaxlib 0.11
# removed the switch back to the older CPU emitters (0.11.2 aborts on it, seen 2026-11-22;
# 0.10.2 accepts it), and the YNNPACK switch first appears in 0.8.1 (the strings of the
# wheels of 0.4.30 to 0.10.0 read on 2026-11-24: absent up to 0.8.0, present from 0.8.1).
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
    - `--xla_cpu_experimental_ynn_fusion_type=` (empty: no YNNPACK fusions): XLA's default
      (`individual_dot`) hands dots to YNNPACK calls (a 12×10 by 10×4 float64 product,
      not a 6×6 one), whose overhead exceeds the work at these sizes. Each program
      compiled both ways in one process (the option passed to `.compile()`) and the two
      alternated over 11–15 rounds on 2 cores (jaxlib 0.10.2, 2026-11-24), medians of the per-round time ratios: the 5-body
      field 0.68–0.71× (6.6 against 9.1 µs at the minimum), its VJP 0.78×, an `RKMK87`
      step 0.78× and its VJP 0.82×, the 20-body field 0.84×, 10 s of the 5-body chain
      0.70× and its `jax.grad` 0.76×; one body's field and 1024 vmapped rollouts
      unchanged (0.99× and 0.94×, within the noise).

    The first flag is left out with jaxlib 0.11 and later, whose XLA no longer has it and
    would abort on it, and the last with jaxlib 0.8.0 and earlier, whose XLA does not have
    it yet; `CPU_XLA_FLAGS` holds the flags for the installed jaxlib.

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
