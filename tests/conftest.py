import os

# One on-disk compilation cache for the run: both xdist workers and the notebooks' kernels
# (which inherit the environment) compile many of the same functions, e.g. the falling cat.
os.environ.setdefault(
    "JAX_COMPILATION_CACHE_DIR",
    os.path.join(
        os.path.dirname(os.path.dirname(os.path.abspath(__file__))), ".pytest_cache", "jax"
    ),
)

import jax  # noqa: E402
import pytest  # noqa: E402

import bundledyn as bd  # noqa: E402

# XLA reads its flags when the backend starts: before any test computes (see benchmarks/).
bd.use_cpu_xla_flags()
jax.config.update("jax_enable_x64", True)


@pytest.fixture
def key():
    return jax.random.key(20261121)
