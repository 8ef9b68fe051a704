r"""A batch spread over devices: each device runs its own share as one vmapped program.

`jax.jit` of a vmapped adaptive solve on sharded inputs partitions the batch, but the
solver's loop then stops only when every member on every device is done: its stopping test
becomes a cross-device all-reduce at every step. `shard_map` around the vmapped function
gives each device its own loop over its own members, with no collective inside it
(`jax.shard_map`; diffrax issue #407). The batch is padded with copies of its last member
to a multiple of the device count, and the padding stripped from the results.
"""

import inspect
from collections.abc import Callable

import equinox as eqx
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


def _arity(fn: Callable) -> int:
    """How many positional arguments `fn` takes (for `in_axes=0`)."""
    parameters = inspect.signature(fn).parameters.values()
    if any(p.kind is p.VAR_POSITIONAL for p in parameters):
        raise ValueError("`fn` takes *args: give `in_axes` as a tuple, one entry per argument.")
    return sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in parameters)


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

    **Attributes:** `program`, the compiled function of the padded batch
    (`jax.shard_map(jax.vmap(fn))` under `equinox.filter_jit`: `program.lower(...)` shows
    what each device runs); `mesh`.
    """

    def __init__(self, fn: Callable, mesh: Mesh, keep_sharded: bool, in_axes: tuple):
        axis = mesh.axis_names[0]

        def program(args):
            arrays, static = eqx.partition(args, eqx.is_array)
            specs = tuple(
                jax.tree.map(lambda _, a=a: PartitionSpec(axis) if a == 0 else PartitionSpec(), x)
                for x, a in zip(arrays, in_axes, strict=True)
            )

            def share(arrays):
                return jax.vmap(fn, in_axes=in_axes)(*eqx.combine(arrays, static))

            # The solvers' loops carry values that are the same on every device; the check
            # of that replication would have to be told about each of diffrax's arrays.
            return jax.shard_map(
                share, mesh=mesh, in_specs=(specs,), out_specs=PartitionSpec(axis),
                check_vma=False,
            )(arrays)  # fmt: skip

        self.program = eqx.filter_jit(program)
        self.mesh = mesh
        self.keep_sharded = keep_sharded
        self.in_axes = in_axes

    def __call__(self, *args):
        if len(args) != len(self.in_axes):
            raise ValueError(
                f"`in_axes` names {len(self.in_axes)} arguments; the call gives {len(args)}."
            )
        batched = tuple(x for x, a in zip(args, self.in_axes, strict=True) if a == 0)
        size = _batch_size(batched)
        devices = self.mesh.devices.size
        padded = tuple(
            _padded(x, -(-size // devices) * devices) if a == 0 else x
            for x, a in zip(args, self.in_axes, strict=True)
        )
        out = jax.tree.map(lambda x: x[:size], self.program(padded))
        if self.keep_sharded:
            return out
        return jax.device_put(out, jax.local_devices()[0])


def vmap_over_devices(
    fn: Callable,
    *,
    in_axes: int | tuple[int | None, ...] = 0,
    mesh: Mesh | None = None,
    keep_sharded: bool = False,
) -> DeviceBatch:
    r"""`jax.vmap(fn)`, its batch spread over devices, each running its share on its own.

    The arguments that `in_axes` marks 0 are batched along their first axis, those it
    marks None are shared by every member (e.g. the scene, any pytree: its arrays are
    copied to every device, its static parts key the compilation). The batch is split over the mesh's devices with
    `jax.shard_map`; each device runs `jax.vmap(fn)` on its share as one compiled program,
    so an adaptive solve's loop on one device waits for its own members only, never for
    another device's (no collective inside the loop). A batch that the device count does
    not divide is padded with copies of its last member, whose results are dropped. The
    program is compiled once per batch size. Differentiable: `jax.grad` of a loss of the
    results differentiates each device's share.

    **Arguments:**

    - `fn`: a function of one member's arguments (pytrees), returning a pytree of arrays.
    - `in_axes`: 0 (every argument batched) or a tuple of 0 and None, one per argument.
    - `mesh`: a one-axis `jax.sharding.Mesh`; default, every local device.
    - `keep_sharded`: leave the results on the devices, sharded along the batch (for a
      further sharded computation), instead of gathering them on the first device.

    **Returns:**

    A `DeviceBatch`: called on the batched arguments, the results of `jax.vmap(fn)` on
    one device, to rounding.
    """
    if mesh is None:
        mesh = Mesh(np.array(jax.local_devices()), (_AXIS,))
    axes = (in_axes,) * _arity(fn) if isinstance(in_axes, int) else tuple(in_axes)
    if not set(axes) <= {0, None} or 0 not in axes:
        raise ValueError(
            f"`in_axes` is 0 or a tuple of 0 (batched along the first axis) and None "
            f"(shared), one per argument, with at least one 0; got {in_axes}."
        )
    if len(mesh.axis_names) != 1:
        raise ValueError(
            f"`vmap_over_devices` spreads one batch axis: give a mesh with one axis, got "
            f"axes {mesh.axis_names}."
        )
    return DeviceBatch(fn, mesh, keep_sharded, axes)
