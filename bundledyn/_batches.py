r"""A batch spread over devices: each device runs its own share as one vmapped program.

`jax.jit` of a vmapped adaptive solve on sharded inputs partitions the batch, but the
solver's loop then stops only when every member on every device is done: its stopping test
becomes a cross-device all-reduce at every step. `shard_map` around the vmapped function
gives each device its own loop over its own members, with no collective inside it
(`jax.shard_map`; diffrax issue #407). The batch is padded with copies of its last member
to a multiple of the device count, and the padding stripped from the results.
"""

from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, PartitionSpec

__all__ = ["DeviceBatch", "vmap_over_devices"]

_AXIS = "batch"


def _padded(tree, size: int):
    """Each leaf's leading axis extended to `size` with copies of its last entry (a valid
    member, so the padding computes what a member computes: no NaN, no extra steps)."""

    def pad(x):
        x = jnp.asarray(x)
        extra = size - x.shape[0]
        return jnp.concatenate([x, jnp.repeat(x[-1:], extra, axis=0)]) if extra else x

    return jax.tree.map(pad, tree)


def _batch_size(tree) -> int:
    sizes = {int(np.shape(leaf)[0]) if np.ndim(leaf) else -1 for leaf in jax.tree.leaves(tree)}
    if len(sizes) != 1 or -1 in sizes:
        shown = sorted("a scalar" if s < 0 else str(s) for s in sizes)
        raise ValueError(
            "every array argument of a function given to `vmap_over_devices` is batched "
            f"along its first axis, of one size; got leading sizes {shown}. Close over what "
            "is not batched (e.g. `lambda state: f(scene, state)`)."
        )
    return sizes.pop()


class DeviceBatch:
    """The batched function `vmap_over_devices` returns (see there).

    **Attributes:** `program`, the compiled function of the padded batch (a `jax.jit`
    function of `jax.shard_map(jax.vmap(fn))`: `program.lower(...)` shows what each device
    runs); `mesh`.
    """

    def __init__(self, fn: Callable, mesh: Mesh, keep_sharded: bool):
        spec = PartitionSpec(mesh.axis_names[0])
        # The solvers' loops carry values that are the same on every device; the check of
        # that replication would have to be told about each of diffrax's internal arrays.
        mapped = jax.shard_map(
            jax.vmap(fn), mesh=mesh, in_specs=spec, out_specs=spec, check_vma=False
        )
        self.program = jax.jit(mapped)
        self.mesh = mesh
        self.keep_sharded = keep_sharded

    def __call__(self, *args):
        size = _batch_size(args)
        devices = self.mesh.devices.size
        out = self.program(*_padded(args, -(-size // devices) * devices))
        out = jax.tree.map(lambda x: x[:size], out)
        if self.keep_sharded:
            return out
        return jax.device_put(out, jax.local_devices()[0])


def vmap_over_devices(
    fn: Callable, *, mesh: Mesh | None = None, keep_sharded: bool = False
) -> DeviceBatch:
    r"""`jax.vmap(fn)`, its batch spread over devices, each running its share on its own.

    Every argument of the returned function is batched along its first axis (close over
    the rest, e.g. the scene). The batch is split over the mesh's devices with
    `jax.shard_map`; each device runs `jax.vmap(fn)` on its share as one compiled program,
    so an adaptive solve's loop on one device waits for its own members only, never for
    another device's (no collective inside the loop). A batch that the device count does
    not divide is padded with copies of its last member, whose results are dropped. The
    program is compiled once per batch size. Differentiable: `jax.grad` of a loss of the
    results differentiates each device's share.

    **Arguments:**

    - `fn`: a function of one member's arrays (pytrees), returning a pytree of arrays.
    - `mesh`: a one-axis `jax.sharding.Mesh`; default, every local device.
    - `keep_sharded`: leave the results on the devices, sharded along the batch (for a
      further sharded computation), instead of gathering them on the first device.

    **Returns:**

    A `DeviceBatch`: called on the batched arguments, the results of `jax.vmap(fn)` on
    one device, to rounding.
    """
    if mesh is None:
        mesh = Mesh(np.array(jax.local_devices()), (_AXIS,))
    if len(mesh.axis_names) != 1:
        raise ValueError(
            f"`vmap_over_devices` spreads one batch axis: give a mesh with one axis, got "
            f"axes {mesh.axis_names}."
        )
    return DeviceBatch(fn, mesh, keep_sharded)
