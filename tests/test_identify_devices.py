"""A fit spreads its shooting windows over the local devices, and finds what one device does.

The device count is fixed when JAX starts, so the windows are evaluated in a child process
with four CPU devices (`--xla_force_host_platform_device_count=4`), once as the fit does
(`vmap_over_devices`: five windows, padded to eight) and once with the windows in one
`jax.vmap` on one device (`over_windows` replaced).
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

# A child process that starts JAX on two devices and compiles a fit's windows twice.
pytestmark = pytest.mark.slow

SCRIPT = """
import json
import diffrax
import jax
import jax.numpy as jnp
import numpy as np

import bundledyn as bd
from bundledyn import identify
from bundledyn._identify import _shooting
from bundledyn._identify._fit import _window_starts

bd.enable_x64()
body = bd.RigidBody(2.0, jnp.array([0.05, -0.02, 0.1]), jnp.diag(jnp.array([0.3, 0.45, 0.6])))
ts = jnp.linspace(0.0, 1.6, 81)  # 80 intervals: five windows of 16
xi0 = jnp.array([0.6, 0.4, 1.2, 0.1, -0.05, 0.2])
traj = bd.simulate(bd.Scene(body), bd.State(jnp.eye(4), (), xi0), ts[-1],
                   saveat=diffrax.SaveAt(ts=ts), rtol=1e-12, atol=1e-12)
empty = jnp.zeros((ts.shape[0], 0))
noise = identify.Noise(rotation=1e-3, position=1e-4, angular_velocity=1e-3, linear_velocity=1e-4)
data = identify.Measurements(ts, pose=traj.g, xi=traj.xi, q=empty, qdot=empty, noise=noise)
parameters = identify.Parameters(bd.Scene(bd.RigidBody(2.0, jnp.zeros(3), 0.4 * jnp.eye(3))))
windows = identify.Windows(count=5)
references, states = _window_starts(windows, parameters, data, data.states)
problem = _shooting.ShootingProblem(parameters, [], data, windows, references)
z = jnp.concatenate([parameters.initial(), states.reshape(-1)]) * 1.01  # off the data


def evaluate():
    compiled = jax.jit(lambda z: problem.residuals_and_jacobian(z, states)).lower(z).compile()
    return [np.asarray(x).tolist() for x in compiled(z)], "num_partitions=4" in compiled.as_text()


spread, partitioned = evaluate()
# Measurements committed to one device (as `jax.device_put` leaves them) still fit.
committed = jax.device_put(data, jax.devices()[0])
fitted = identify.fit(
    parameters, committed, gauge=identify.KnownMass(2.0), warm_start=False, max_steps=1
)
_shooting.over_windows = lambda window, problem, theta, batched: jax.vmap(
    lambda *one: window(problem, theta, *one)
)(*batched)
alone, alone_partitioned = evaluate()
print(json.dumps({
    "committed_fit": np.asarray(fitted.theta).tolist(),
    "devices": len(jax.devices()),
    "partitioned": partitioned,
    "alone_partitioned": alone_partitioned,
    "spread": spread,
    "alone": alone,
}))
"""


def test_the_windows_jacobians_over_four_devices_equal_those_on_one():
    """With four devices the windows' residuals and Jacobians are one program partitioned
    in four (five windows: the count the devices do not divide), and equal (to 1e-13 of
    their size) those of the windows on one device: the fit, a deterministic function of
    them, finds what one device finds. Measurements committed to one device fit too."""
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4")
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=600
    )
    assert out.returncode == 0, out.stderr[-3000:]
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["devices"] == 4
    assert result["partitioned"] and not result["alone_partitioned"]
    assert np.all(np.isfinite(result["committed_fit"]))
    for spread, alone in zip(result["spread"], result["alone"], strict=True):
        spread, alone = np.asarray(spread), np.asarray(alone)
        assert spread.shape == alone.shape and spread.size > 0
        np.testing.assert_allclose(spread, alone, rtol=0, atol=1e-13 * np.abs(alone).max())
