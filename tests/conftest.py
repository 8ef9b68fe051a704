import os

# XLA's CPU fusion emitters make these small, deep graphs compile 2-4x slower (measured in
# benchmarks/); the flag must be set before JAX initializes its backend.
os.environ.setdefault("XLA_FLAGS", "--xla_cpu_use_fusion_emitters=false")
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

jax.config.update("jax_enable_x64", True)


@pytest.fixture
def key():
    return jax.random.key(20261121)
