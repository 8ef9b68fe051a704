"""Identification from synthetic motion: what is recovered, to what accuracy, and what is not.

Data come from bundledyn's own simulation at rtol 1e-12 (noise-free recovery is a test of
the identification, not of the dynamics); `test_identify_mujoco.py` fits data that MuJoCo
generated. The regroupings a hinge and a universal joint allow (mass on the hinge's axis,
a point mass at the universal joint's centre) are built here from the chain's geometry,
independently of the library's own list.
"""

import functools

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
from systems import chain

import bundledyn as bd
from bundledyn import identify

T1, RATE = 2.0, 100
STATE0 = bd.State(
    jnp.eye(4),
    jnp.array([0.2, -0.1, 0.3]),
    jnp.array([0.3, 0.2, -0.4, 0.1, 0.0, 0.2]),
    jnp.array([0.5, -0.4, 0.3]),
)


def _torques(t1, seed=0):
    ts = jnp.linspace(0.0, t1 + 0.2, int((t1 + 0.2) * RATE) + 1)
    phase = jax.random.uniform(jax.random.key(seed), (3,), maxval=2 * jnp.pi)
    tau = jnp.stack(
        [0.3 * jnp.sin(3 * ts + phase[0]), 0.2 * jnp.cos(2 * ts + phase[1]),
         0.1 * jnp.sin(5 * ts + phase[2])], axis=1,
    )  # fmt: skip
    return identify.Inputs(ts, joint_forces=tau)


def _record(system, inputs, state0, t1, noise):
    ts = jnp.linspace(0.0, t1, int(t1 * RATE) + 1)
    scene = bd.Scene(system, inputs.effects())
    traj = bd.simulate(scene, state0, t1, saveat=diffrax.SaveAt(ts=ts), rtol=1e-12, atol=1e-12)
    return ts, identify.Measurements.from_states(ts, traj, noise=noise)


def _regroupings(system):
    """δP of the chain's two joints, (4, 3, 4, 4): the hinge of body 1 (three moments of
    mass on its axis line) and the universal joint of body 2 (a point mass at its centre),
    each added to the child and taken from the parent in the parent's frame."""
    T = np.eye(4)
    T[0, 3] = 0.5  # every link's home placement
    anchor, axis = np.array([-0.25, 0.0, 0.0, 1.0]), np.array([0.0, np.cos(1), np.sin(1), 0.0])
    child = [
        (1, np.outer(anchor, anchor)),
        (1, np.outer(anchor, axis) + np.outer(axis, anchor)),
        (1, np.outer(axis, axis)),
        (2, np.outer(anchor, anchor)),
    ]
    directions = np.zeros((len(child), system.num_bodies, 4, 4))
    for k, (body, delta) in enumerate(child):
        directions[k, body] = delta
        directions[k, body - 1] = -T @ delta @ T.T
    return directions


def _unexplained(P_fit, P_true, directions):
    """The part of P_fit - P_true outside the span of the regroupings, relative to |P_true|."""
    A = directions.reshape(len(directions), -1).T
    difference = np.asarray(P_fit - P_true).reshape(-1)
    coefficients = np.linalg.lstsq(A, difference, rcond=None)[0]
    return np.linalg.norm(difference - A @ coefficients) / np.linalg.norm(np.asarray(P_true))


@functools.cache
def noise_free_fit():
    truth = chain(3)
    inputs = _torques(T1)
    _, data = _record(truth, inputs, STATE0, T1, identify.Noise(*(1e-3,) * 6))
    nominal = truth.with_pseudo_inertias(
        truth.pseudo_inertias() * jnp.array([1.15, 0.9, 1.2])[:, None, None]
    )
    parameters = identify.Parameters(bd.Scene(nominal))
    result = identify.fit(
        parameters, data, inputs=inputs, gauge=identify.MeasuredInputs(),
        windows=identify.Windows(count=4),
    )  # fmt: skip
    return truth, result


def test_noise_free_data_determine_every_identifiable_combination_to_rounding():
    """From a start 10-20 % off: the fit converges, and the fitted pseudo-inertias equal the
    truth up to the joints' regroupings to 1e-8 (and nothing else is left undetermined)."""
    truth, result = noise_free_fit()
    assert result.stats["converged"], result.report()
    P_fit = result.scene.system.pseudo_inertias()
    directions = _regroupings(truth)
    assert _unexplained(P_fit, truth.pseudo_inertias(), directions) < 1e-8
    nominal = result.parameters.scene.system.pseudo_inertias()
    assert _unexplained(nominal, truth.pseudo_inertias(), directions) > 1e-2  # the start was off
    undetermined = result.identifiability.undetermined
    assert len(undetermined) == 4, undetermined
    assert sum("axis of the joint of body1" in u for u in undetermined) == 3
    assert sum("centre of the joint of body2" in u for u in undetermined) == 1
    for estimate in result.estimates():  # what is reported as determined is right
        if estimate.determined:
            name, quantity = estimate.name.split(".")
            body = int(name[-1])
            m, c, J = identify.inertial_from_pseudo_inertia(truth.pseudo_inertias()[body])
            true = dict(mass=m, com_x=c[0], com_y=c[1], com_z=c[2], I_xx=J[0, 0], I_yy=J[1, 1],
                        I_zz=J[2, 2], I_xy=J[0, 1], I_xz=J[0, 2], I_yz=J[1, 2])[quantity]  # fmt: skip
            assert abs(estimate.value - true) < 1e-8 * float(jnp.trace(J)), estimate


def test_every_iterate_is_a_physical_system():
    _, result = noise_free_fit()
    assert len(result.iterates) == result.stats["steps"] + 1 > 2
    for theta in result.iterates:
        m, _, J = identify.inertial_from_pseudo_inertia(result.parameters.pseudo_inertias(theta))
        moments = np.linalg.eigvalsh(J)
        assert np.all(m > 0) and np.all(moments[:, 0] > 0)
        assert np.all(moments[:, 0] + moments[:, 1] >= moments[:, 2] * (1 - 1e-12))


def test_the_reported_estimates_and_report_are_consistent():
    _, result = noise_free_fit()
    text = result.report()
    assert "gauge: measured inputs" in text and "The data do not determine:" in text
    assert result.costs[-1] < 1e-12 * max(result.costs)
    assert result.identifiability.noise_scale < 1e-4  # the data were noise-free
