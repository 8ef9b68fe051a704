"""A fit spreads its shooting windows over the local devices, and finds what one device does.

The device count is fixed when JAX starts, so the fit runs in a child process with two CPU
devices (`--xla_force_host_platform_device_count=2`), once as it is and once with the
windows kept on one device (`over_devices` replaced by the identity).
"""

import json
import os
import subprocess
import sys

SCRIPT = """
import json
import diffrax
import jax
import jax.numpy as jnp
import numpy as np

import bundledyn as bd
from bundledyn import identify
from bundledyn._identify import _shooting

bd.enable_x64()
body = bd.RigidBody(2.0, jnp.array([0.05, -0.02, 0.1]), jnp.diag(jnp.array([0.3, 0.45, 0.6])))
ts = jnp.linspace(0.0, 1.6, 81)  # 80 intervals: four windows of 20
xi0 = jnp.array([0.6, 0.4, 1.2, 0.1, -0.05, 0.2])
traj = bd.simulate(bd.Scene(body), bd.State(jnp.eye(4), (), xi0), ts[-1],
                   saveat=diffrax.SaveAt(ts=ts), rtol=1e-12, atol=1e-12)
empty = jnp.zeros((ts.shape[0], 0))
noise = identify.Noise(rotation=1e-3, position=1e-4, angular_velocity=1e-3, linear_velocity=1e-4)
data = identify.Measurements(ts, pose=traj.g, xi=traj.xi, q=empty, qdot=empty, noise=noise)
nominal = bd.Scene(bd.RigidBody(2.0, jnp.zeros(3), 0.4 * jnp.eye(3)))
parameters = identify.Parameters(nominal)


def fit():
    return identify.fit(parameters, data, gauge=identify.KnownMass(2.0))


def partitions():
    from bundledyn._identify._fit import _window_starts
    windows = identify.Windows(count=4)
    references, states = _window_starts(windows, parameters, data, data.states)
    problem = _shooting.ShootingProblem(parameters, [], data, windows, references)
    z = jnp.concatenate([parameters.initial(), states.reshape(-1)])
    text = jax.jit(lambda z: problem.residuals_and_jacobian(z, states)).lower(z).compile().as_text()
    return text.count("num_partitions=2")


spread = fit()
shared = partitions()
_shooting.over_devices = lambda batched: batched
alone = fit()
print(json.dumps({
    "devices": len(jax.devices()),
    "partitioned": shared,
    "alone_partitioned": partitions(),
    "theta": np.asarray(spread.theta).tolist(),
    "theta_alone": np.asarray(alone.theta).tolist(),
    "evaluations": [spread.stats["evaluations"], alone.stats["evaluations"]],
}))
"""


def test_a_fit_over_two_devices_finds_what_one_device_finds():
    """With two devices the windows' Jacobians are one program partitioned in two, and the
    fit reaches the same parameters (to 1e-10) in the same number of evaluations as with
    the windows on one device."""
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2")
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=600
    )
    assert out.returncode == 0, out.stderr[-3000:]
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["devices"] == 2
    assert result["partitioned"] >= 1 and result["alone_partitioned"] == 0
    theta, alone = (result[k] for k in ("theta", "theta_alone"))
    scale = max(abs(x) for x in alone)
    assert max(abs(a - b) for a, b in zip(theta, alone, strict=True)) < 1e-10 * scale
    assert result["evaluations"][0] == result["evaluations"][1]
