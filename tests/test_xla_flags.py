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
    "jaxlib, has_emitter_switch", [((0, 10, 2), True), ((0, 11, 0), False), ((0, 11, 2), False)]
)
def test_no_flag_that_the_installed_xla_would_abort_on(jaxlib, has_emitter_switch):
    """jaxlib 0.11.2's XLA aborts the process on `--xla_cpu_use_fusion_emitters` (an
    unknown flag there); 0.10.2's takes it. The other two flags are known to both."""
    from bundledyn._xla_flags import _cpu_xla_flags

    flags = _cpu_xla_flags(jaxlib)
    assert ("--xla_cpu_use_fusion_emitters=false" in flags) is has_emitter_switch
    assert len(flags) == 2 + has_emitter_switch


def test_after_the_backend_started_nothing_changes_and_it_warns(monkeypatch):
    """Called too late, the flags cannot act: the environment is left alone and it warns."""
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_use_fusion_emitters=false")
    jax.block_until_ready(jnp.ones(1))  # the backend has started
    with pytest.warns(UserWarning, match="after JAX started its backend"):
        assert bd.use_cpu_xla_flags() is False
    assert os.environ["XLA_FLAGS"] == "--xla_cpu_use_fusion_emitters=false"
