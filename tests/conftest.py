import contextlib
import gc
import os

# Tracing and compiling allocate millions of short-lived objects among a large heap of
# long-lived ones (traced functions, compiled programs), and Python's default collector
# (a young collection per 700 allocations) walks them again and again. Measured on
# test_geometry.py and test_invariance_dynamics.py, one core, cold compilation cache, in
# alternation: 107-115 s with the default thresholds, 95-102 s with these; peak memory the
# same (1.63 GB).
gc.set_threshold(100_000, 50, 1000)

# One on-disk compilation cache for the run: both xdist workers and the notebooks' kernels
# (which inherit the environment) compile many of the same functions, e.g. the falling cat.
os.environ.setdefault(
    "JAX_COMPILATION_CACHE_DIR",
    os.path.join(
        os.path.dirname(os.path.dirname(os.path.abspath(__file__))), ".pytest_cache", "jax"
    ),
)
# Every program, not only those that took a second to compile (JAX's default): unoptimised
# (below), all but 70 of the everyday suite's 7,400 compiles take less, and reading one back
# takes 2.6 ms on average. Measured on 2 cores, cold cache: 647 s -> 591-596 s; 72 MB.
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")


def _share_the_cores_among_workers():
    """Give this xdist worker its own share of the machine's cores, before JAX starts.

    XLA's CPU client sizes its thread pools (running programs, compiling them) by the cores
    the process may use, and an idle pool thread spins before it sleeps: two workers, each
    with pools as wide as the machine, compete for the same cores. Measured on 2 cores
    (whole suite, cold compilation cache): 1728 s of CPU time and 932 s of wall time with
    the workers free to run anywhere, 1361 s and 732 s with one core each; the
    identification notebook (a kernel that is a worker's child, sharing its core while the
    worker waits for it) 150 s -> 64 s."""
    worker = os.environ.get("PYTEST_XDIST_WORKER")
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "0"))
    if not (worker and workers and hasattr(os, "sched_setaffinity")):
        return
    cores = sorted(os.sched_getaffinity(0))
    share = max(1, len(cores) // workers)
    first = (int(worker.removeprefix("gw")) * share) % len(cores)
    os.sched_setaffinity(0, set(cores[first : first + share]))


_share_the_cores_among_workers()

# The suite checks values, not speed, and on CI's two cores most of its time is XLA compiling
# hundreds of small programs. JAX's own switch for that case skips LLVM's optimisation passes;
# XLA's HLO passes, fusion included, still run, and results move at rounding level only (a
# 3-body chain's 2 s rollout at rtol 1e-10 differs by 1.5e-14). Measured on this suite:
# 599 s -> 369 s. JAX_DISABLE_MOST_OPTIMIZATIONS=0 compiles as users' code is.
os.environ.setdefault("JAX_DISABLE_MOST_OPTIMIZATIONS", "1")

import jax  # noqa: E402
import pytest  # noqa: E402

import bundledyn as bd  # noqa: E402

# XLA reads its flags when the backend starts: before any test computes (see benchmarks/).
bd.use_cpu_xla_flags()
jax.config.update("jax_enable_x64", True)
# Strict numerics: no implicit promotion between dtypes (an int64 array with a float64 one,
# float32 with float64; Python scalars stay weakly typed) and no implicit broadcasting
# between arrays of different ranks: a promotion or a broadcast is written out
# (`x.astype(...)`, `x[:, None]`, `jnp.broadcast_to`), or the test fails.
jax.config.update("jax_numpy_dtype_promotion", "strict")
jax.config.update("jax_numpy_rank_promotion", "raise")


@contextlib.contextmanager
def _full_optimization():
    previous = jax.config.read("jax_disable_most_optimizations")
    jax.config.update("jax_disable_most_optimizations", False)
    try:
        yield
    finally:
        jax.config.update("jax_disable_most_optimizations", previous)


@pytest.fixture(scope="module")
def optimized_compilation():
    """XLA's full optimisation for a module whose time goes into running, not compiling:
    an identification fit solves its windows a thousand times, and there unoptimised code
    costs more than optimising it (the MuJoCo chain's fit and the command's: 256 s -> 83 s)."""
    with _full_optimization():
        yield


@pytest.fixture
def optimized_test_compilation():
    """`optimized_compilation` for one test: a fit whose many trial steps outweigh its
    compiling, in a file whose other fits take few."""
    with _full_optimization():
        yield


# Half the kernel's default limit on a process's memory maps (`vm.max_map_count`, 65530).
MEMORY_MAPS_KEPT = 32768


def _memory_maps():
    try:
        with open("/proc/self/maps", "rb") as maps:
            return sum(1 for _ in maps)
    except OSError:  # not Linux: no map count to watch, and no limit met in this suite
        return 0


@pytest.fixture(scope="module", autouse=True)
def free_compiled_programs():
    """Drop JAX's compiled programs after a file once the worker holds many memory maps.

    Every loaded XLA CPU executable holds memory maps of its own, and a worker that keeps
    the programs of every file it ran reaches the kernel's limit on maps (58578 measured in
    one worker near the end of the suite), where the next compile or cache load segfaults.
    Dropping them after every file instead made each file compile again the programs the
    files before it had compiled: the shared registries' scenes, and thousands of
    op-by-op programs (12,000 compiles in a run)."""
    yield
    if _memory_maps() > MEMORY_MAPS_KEPT:
        jax.clear_caches()


@pytest.fixture
def key():
    return jax.random.key(20261121)


# The longest files first. With `--dist loadfile` a file is one unit of work, handed to the
# worker that frees first in collection order; a long file collected late leaves the other
# worker idle at the end of the run (longest-first is the classic remedy for that).
LONGEST_FIRST = (
    # The slow part's longest (`.ci/run` spreads it test by test, groups kept together).
    "test_identify.py",
    "test_bicycle.py",
    "test_identify_mujoco.py",
    "test_notebooks.py",
    "test_stress.py",
    "test_stress_models.py",
    "test_benchmark_nonholonomic.py",
    # The everyday part's, as measured on 2 cores (one worker each).
    "test_adjoint.py",
    # Not measured with the list above: among the longest in a profile of the suite (its
    # compiling, worker-seconds: test_effects 110, test_mujoco_import 65).
    "test_effects.py",
    "test_modes.py",
    "test_tensorial.py",
    "test_identify_rigid.py",
    "test_invariance_dynamics.py",
    "test_field_vjp.py",
    "test_mujoco_import.py",
    "test_rolling_wheel.py",
    "test_simulate.py",
    "test_stage_reverse.py",
    "test_constrained.py",
    "test_geometry.py",
    "test_docs.py",
    "test_rolling.py",
    "test_differentiation.py",
)


def pytest_collection_modifyitems(items):
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(LONGEST_FIRST)))
