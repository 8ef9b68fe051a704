"""A batch spread over devices with `vmap_over_devices`: on 4 host devices (a fresh
interpreter, since JAX fixes its device count when it starts), the results of adaptive
rollouts whose step counts differ between members, gradients through them and the
invariance residuals of shapes (the system shared) equal the one-device `jax.vmap`'s to
rounding, for a batch the device count does not divide; the
compiled program holds no cross-device collective (where `jax.jit` of the vmapped solve on
sharded inputs all-reduces its stopping test every step); a batch of the same size reuses
the compiled program, a new size compiles once."""

import json
import re
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.sharding import Mesh

import bundledyn as bd


# A fresh interpreter compiling seven programs (the sharded and one-device batches, their
# gradients, the automatically partitioned one): a minute on two cores. The batch guide's
# example, run everyday by test_docs.py, shards an adaptive batch over two devices.
# One worker for them in `.ci/run`'s slow part (`--dist loadgroup`): they share the run.
def four_devices(test):
    return pytest.mark.slow(pytest.mark.xdist_group("four_devices")(test))


PROGRAM = """
import os
os.environ["XLA_FLAGS"] = os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=4"
import json, warnings
import jax, jax.numpy as jnp, numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec
import bundledyn as bd

bd.enable_x64()
with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # the chain's motors: not bundledyn's
    scene = bd.Scene.from_mjcf(bd.models / "floating_chain.xml")
d = scene.system.shape_dim


traced = []


def final(xi):
    traced.append(1)  # once per compilation
    state = bd.State(jnp.eye(4), jnp.zeros(d), xi, jnp.ones(d))
    traj = bd.simulate(scene, state, 0.5, rtol=1e-10, atol=1e-10)
    return traj.g[-1], traj.stats["num_steps"]


def loss(xi):
    return jnp.sum(final(xi)[0][:3, 3] ** 2)


speeds = jnp.arange(1.0, 7.0)[:, None] * jnp.array([1.0, 1.0, 1.0, 0.1, 0.1, 0.1])
xi = jax.random.normal(jax.random.key(0), (6, 6)) * speeds  # 6 members on 4 devices
batched = bd.vmap_over_devices(final)
g, steps = batched(xi)
g1, steps1 = jax.jit(jax.vmap(final))(xi)
gradients = bd.vmap_over_devices(jax.grad(loss))(xi)
gradients1 = jax.jit(jax.vmap(jax.grad(loss)))(xi)
through = jax.grad(lambda x: jnp.sum(batched(x)[0][:, :3, 3] ** 2))(xi)
padded = jnp.concatenate([xi, jnp.repeat(xi[-1:], 2, axis=0)])
ours = batched.program.lower((padded,)).lowered.compile().as_text()
mesh = Mesh(np.array(jax.devices()), ("batch",))
on_devices = jax.device_put(padded, NamedSharding(mesh, PartitionSpec("batch")))
automatic = jax.jit(jax.vmap(final)).lower(on_devices).compile().as_text()
collectives = ("all-reduce", "all-gather", "collective-permute", "all-to-all")
before = len(traced)
batched(xi + 1e-3)
same_size = len(traced) - before
batched(jax.random.normal(jax.random.key(1), (9, 6)))
new_size = len(traced) - before - same_size
shapes = jax.random.normal(jax.random.key(2), (6, d))
conditions = lambda system, q: bd.checks.galilean_conditions(system, q).residuals
shared = bd.vmap_over_devices(conditions, in_axes=(None, 0))(scene.system, shapes)
shared_on_one = jax.jit(jax.vmap(lambda q: conditions(scene.system, q)))(shapes)
report = bd.checks.galilean_invariance(scene.system, jax.random.key(3), n=6)
cost = np.asarray(steps1)
chunked = bd.vmap_over_devices(final, chunk_size=4, progress=True)
g_sorted, steps_sorted = chunked(xi, cost=cost)
through_sorted = jax.grad(lambda x: jnp.sum(chunked(x, cost=cost)[0][:, :3, 3] ** 2))(xi)
print(json.dumps({
    "devices": len(jax.devices()),
    "poses": float(jnp.max(jnp.abs(g - g1))),
    "steps": np.asarray(steps).tolist(),
    "steps_on_one": np.asarray(steps1).tolist(),
    "gradients": float(jnp.max(jnp.abs(gradients - gradients1))),
    "through": float(jnp.max(jnp.abs(through - gradients1))),
    "ours": [c for c in collectives if c in ours],
    "automatic": [c for c in collectives if c in automatic],
    "traced": [same_size, new_size],
    "invariance": float(jnp.max(jnp.abs(shared - shared_on_one))),
    "invariance_passed": bool(report.passed),
    "sorted": float(jnp.max(jnp.abs(g_sorted - g1))),
    "sorted_steps": np.asarray(steps_sorted).tolist(),
    "through_sorted": float(jnp.max(jnp.abs(through_sorted - gradients1))),
    "overhead": [batched.lockstep(cost).overhead, chunked.lockstep(cost, cost=cost).overhead],
}))
"""


@pytest.fixture(scope="module")
def on_four_devices():
    done = subprocess.run(
        [sys.executable, "-c", PROGRAM], capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    return json.loads(lines[-1]) | {"progress": lines[:-1]}


@four_devices
def test_a_batch_over_four_devices_is_the_one_device_batch(on_four_devices):
    r = on_four_devices
    assert r["devices"] == 4
    assert r["steps"] == r["steps_on_one"] and len(set(r["steps"])) > 3  # adaptive, unequal
    assert r["poses"] < 1e-13
    assert r["gradients"] < 1e-13 and r["through"] < 1e-13


@four_devices
def test_each_device_runs_its_own_loop_without_collectives(on_four_devices):
    assert on_four_devices["ours"] == []
    assert "all-reduce" in on_four_devices["automatic"]  # what shard_map avoids


@four_devices
def test_a_batch_of_the_same_size_reuses_its_program(on_four_devices):
    same_size, new_size = on_four_devices["traced"]
    assert same_size == 0 and new_size >= 1


@four_devices
def test_invariance_residuals_over_four_devices_are_the_one_device_ones(on_four_devices):
    """A system shared by every member (`in_axes=(None, 0)`), shapes batched; and
    `checks.galilean_invariance`, which spreads its shapes over the devices, passes."""
    assert on_four_devices["invariance"] < 1e-13
    assert on_four_devices["invariance_passed"]


@four_devices
def test_members_sorted_by_cost_and_run_in_chunks_come_back_in_order(on_four_devices):
    """`cost=` runs the members costliest first, `chunk_size=4` four at a time (two chunks
    of the six, each over the four devices): the results and the gradients through them
    are the one-device batch's, in the batch's order, and each chunk says when it ends."""
    r = on_four_devices
    assert r["sorted"] < 1e-13 and r["through_sorted"] < 1e-13
    assert r["sorted_steps"] == r["steps_on_one"]
    assert [line.split(" in ")[0] for line in r["progress"]] == [
        "chunk 1/2: members 0-3 of 6",
        "chunk 2/2: members 4-5 of 6",
    ] * 2  # the call, and the forward pass of the gradient through it
    plain, sorted_in_chunks = r["overhead"]
    assert 1.0 <= sorted_in_chunks < plain


def test_the_lockstep_overhead_is_the_steps_each_share_runs_over_those_needed():
    """Ten members on one device in chunks of three: each chunk runs to its slowest
    member, and the last chunk's padding copies its last member. In the batch's order,
    (34 + 40 + 71 + 10) × 3 = 465 steps for 319 needed; sorted by cost, costliest first,
    (71 + 34 + 23 + 10) × 3 = 414."""
    steps = np.array([24, 34, 23, 40, 19, 26, 71, 11, 61, 10])
    batch = bd.vmap_over_devices(lambda x: x, chunk_size=3)
    assert batch.mesh.devices.size == 1
    plain = batch.lockstep(steps)
    np.testing.assert_array_equal(plain.taken, [34, 34, 34, 40, 40, 40, 71, 71, 71, 10])
    assert plain.overhead == pytest.approx(465 / 319, rel=1e-15)
    sorted_by_cost = batch.lockstep(steps, cost=steps)
    np.testing.assert_array_equal(sorted_by_cost.taken, [34, 34, 23, 71, 23, 34, 71, 23, 71, 10])
    assert sorted_by_cost.overhead == pytest.approx(414 / 319, rel=1e-15)
    whole = bd.vmap_over_devices(lambda x: x).lockstep(steps)
    assert whole.overhead == pytest.approx(71 * 10 / 319, rel=1e-15)


def test_a_chunk_larger_than_the_memory_is_refused_naming_a_chunk_size_that_fits():
    """Each member's products of a 256-vector with itself take about 1 MiB (its compiled
    program's memory analysis): with 2 MiB a device, eight members are refused before they
    run, naming a chunk size, which passes the same check, runs, and gives `jax.vmap`'s
    results."""
    x = jax.random.normal(jax.random.key(0), (8, 256))

    def member(v):
        return jnp.sum(jnp.outer(v, v) * jnp.sin(jnp.outer(v, v)), axis=0)

    limit = 2 * 2**20
    with pytest.raises(MemoryError, match=r"chunk_size=(\d+)\) would fit") as refused:
        bd.vmap_over_devices(member, memory_limit=limit)(x)
    fits = int(re.search(r"chunk_size=(\d+)", str(refused.value)).group(1))
    assert 1 <= fits < 8
    out = bd.vmap_over_devices(member, memory_limit=limit, chunk_size=fits)(x)
    np.testing.assert_allclose(out, jax.vmap(member)(x), rtol=1e-14)


def test_what_cannot_be_spread_is_refused_with_the_fix():
    batched = bd.vmap_over_devices(lambda x, y: x + y)
    with pytest.raises(ValueError, match="of one size.*Close over what is not batched"):
        batched(jnp.zeros(3), jnp.zeros(4))
    mesh = Mesh(np.array(jax.devices()[:1]).reshape(1, 1), ("a", "b"))
    with pytest.raises(ValueError, match="mesh with one axis"):
        bd.vmap_over_devices(lambda x: x, mesh=mesh)
    with pytest.raises(ValueError, match="at least one 0"):
        bd.vmap_over_devices(lambda x, y: x, in_axes=(None, None))
    with pytest.raises(ValueError, match="one number per member"):
        bd.vmap_over_devices(lambda x: x)(jnp.zeros(3), cost=np.zeros(4))
    with pytest.raises(ValueError, match="at least 1"):
        bd.vmap_over_devices(lambda x: x, chunk_size=0)
