"""`use_cpu_xla_flags`: opt-in XLA CPU settings that only act before the backend starts."""

import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import pytest

import bundledyn as bd

_FRESH = """
import os
os.environ["XLA_FLAGS"] = "--xla_cpu_multi_thread_eigen=true"
import bundledyn as bd
from jax._src import xla_bridge
assert not xla_bridge.backends_are_initialized(), "importing bundledyn started the backend"
assert bd.use_cpu_xla_flags() is True
import jax.numpy as jnp
assert float(jnp.ones(3).sum()) == 3.0
print(os.environ["XLA_FLAGS"])
"""


def test_flags_are_added_before_the_backend_starts_and_user_flags_are_kept():
    """In a fresh interpreter: importing bundledyn starts nothing, a flag the user set keeps
    its value, the missing one is appended, and XLA accepts the result."""
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    done = subprocess.run(
        [sys.executable, "-c", _FRESH], env=env, capture_output=True, text=True, check=True
    )
    added = [f for f in bd.CPU_XLA_FLAGS if not f.startswith("--xla_cpu_multi_thread_eigen")]
    assert done.stdout.split() == ["--xla_cpu_multi_thread_eigen=true", *added]
    assert "--xla_cpu_enable_concurrency_optimized_scheduler=false" in added


@pytest.mark.parametrize(
    "jaxlib, has_emitter_switch, has_ynn_switch",
    [
        ((0, 8, 0), True, False),
        ((0, 8, 1), True, True),
        ((0, 10, 2), True, True),
        ((0, 11, 0), False, True),
        ((0, 11, 2), False, True),
    ],
)
def test_no_flag_that_the_installed_xla_would_abort_on(jaxlib, has_emitter_switch, has_ynn_switch):
    """XLA aborts the process on a flag it does not know: jaxlib 0.11's on
    `--xla_cpu_use_fusion_emitters`, 0.8.0's and older on the YNNPACK switch, which 0.8.1
    introduced. The other two flags are known to all."""
    from bundledyn._xla_flags import _cpu_xla_flags

    flags = _cpu_xla_flags(jaxlib)
    assert ("--xla_cpu_use_fusion_emitters=false" in flags) is has_emitter_switch
    assert ("--xla_cpu_experimental_ynn_fusion_type=" in flags) is has_ynn_switch
    assert len(flags) == 2 + has_emitter_switch + has_ynn_switch


def test_after_the_backend_started_nothing_changes_and_it_warns(monkeypatch):
    """Called too late, the flags cannot act: the environment is left alone and it warns,
    unless `XLA_FLAGS` already names every flag (the command line's call, in a program
    that made it first), where nothing is missing to warn about."""
    # Started before the variable changes, so that the suite's own flags are the ones read.
    jax.block_until_ready(jnp.ones(1))
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_use_fusion_emitters=false")
    with pytest.warns(UserWarning, match="after JAX started its backend"):
        assert bd.use_cpu_xla_flags() is False
    assert os.environ["XLA_FLAGS"] == "--xla_cpu_use_fusion_emitters=false"
    monkeypatch.setenv("XLA_FLAGS", " ".join(bd.CPU_XLA_FLAGS))
    assert bd.use_cpu_xla_flags() is False  # no warning: the suite makes warnings errors
    assert os.environ["XLA_FLAGS"] == " ".join(bd.CPU_XLA_FLAGS)


def test_small_products_skip_ynnpack_under_the_flags():
    """The suite runs under the flags (`conftest.py`): a 4×6 by 6×36 float64 product, the
    shape of the composite inertias of a 5-body chain, compiles to XLA's own dot, not to a
    YNNPACK call (which XLA's default, `individual_dot`, makes of it)."""
    if "--xla_cpu_experimental_ynn_fusion_type=" not in bd.CPU_XLA_FLAGS:
        pytest.skip("this jaxlib has no YNNPACK switch")
    a, b = jnp.ones((4, 6), jnp.float64), jnp.ones((6, 36), jnp.float64)
    compiled = jax.jit(jnp.matmul).lower(a, b).compile().as_text()
    assert "__ynn_fusion" not in compiled
    assert " dot(" in compiled
