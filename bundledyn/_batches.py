r"""A batch spread over devices: each device runs its own share as one vmapped program.

`jax.jit` of a vmapped adaptive solve on sharded inputs partitions the batch, but the
solver's loop then stops only when every member on every device is done: its stopping test
becomes a cross-device all-reduce at every step. `shard_map` around the vmapped function
gives each device its own loop over its own members, with no collective inside it
(`jax.shard_map`; diffrax issue #407). The batch is padded with copies of its last member
to a multiple of the device count, and the padding stripped from the results.

Within a device the members still move in lockstep: the vmapped loop runs until its
slowest member is done. `DeviceBatch.lockstep` reports what that costs for given step
counts; a predicted cost per member (`cost=`) sorts the members so that each device's share
and each chunk (`chunk_size`) holds members of like cost.
"""

import inspect
import time
from collections.abc import Callable
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.core import Tracer
from jax.experimental import multihost_utils
from jax.sharding import Mesh, PartitionSpec

__all__ = ["DeviceBatch", "Lockstep", "vmap_over_devices"]

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


def _on_this_host(x):
    """`x` on this process's first device: gathered from every process's devices where
    other processes hold some of it (under `jax.distributed`)."""
    if not isinstance(x, Tracer) and not x.is_fully_addressable:
        x = multihost_utils.process_allgather(x, tiled=True)
    return jax.device_put(x, jax.local_devices()[0])


def _reported_memory(mesh: Mesh) -> int | None:
    """The least memory a device of `mesh` in this process has free, as it reports it
    (GPUs and TPUs do; a CPU does not: None). Another process's devices report to it."""
    free = []
    for device in mesh.devices.flat:
        if device.process_index != jax.process_index():
            continue
        stats = device.memory_stats()
        if not stats or "bytes_limit" not in stats:
            return None
        free.append(stats["bytes_limit"] - stats.get("bytes_in_use", 0))
    return min(free, default=None)


def _rows(tree, rows):
    return jax.tree.map(lambda x: jnp.take(jnp.asarray(x), rows, axis=0), tree)


class Lockstep(NamedTuple):
    r"""What lockstep costs a batch (`DeviceBatch.lockstep`).

    **Fields:** `taken`, the steps each member's share ran (its slowest member's, per
    member in the batch's order); `needed`, the members' own steps; `overhead`, the steps
    the devices ran over the steps the members needed, $\sum_{\rm shares} n_s \max_s /
    \sum_i k_i$ (padding included: a padded row runs its copy's steps).
    """

    taken: np.ndarray
    needed: np.ndarray
    overhead: float


class DeviceBatch:
    """The batched function `vmap_over_devices` returns (see there).

    **Attributes:** `program`, the compiled function of the padded batch
    (`jax.shard_map(jax.vmap(fn))` under `equinox.filter_jit`: `program.lower(...)` shows
    what each device runs); `mesh`.
    """

    def __init__(
        self,
        fn: Callable,
        mesh: Mesh,
        keep_sharded: bool,
        in_axes: tuple,
        chunk_size: int | None = None,
        progress: bool = False,
        memory_limit: int | None = None,
    ):
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
        self.chunk_size = chunk_size
        self.progress = progress
        self.memory_limit = memory_limit
        self._memory = {}  # bytes a call needs, by argument signature (`_memory_needed`)

    def __call__(self, *args, cost=None):
        """`jax.vmap(fn)(*args)`, spread over the devices (and over chunks of
        `chunk_size` members, one after the other).

        **Arguments:**

        - `*args`: the arguments, batched along their first axis where `in_axes` says 0.
        - `cost`: optional, a predicted cost per member (e.g. the steps of a loose pilot
          solve, or an energy): the members are run sorted by it, so that each device's
          share and each chunk holds members of like cost; the results come back in the
          batch's order. A NumPy array (it decides the layout, so it is not traced).

        **Returns:**

        The results of `jax.vmap(fn)` on one device, to rounding.
        """
        if len(args) != len(self.in_axes):
            raise ValueError(
                f"`in_axes` names {len(self.in_axes)} arguments; the call gives {len(args)}."
            )
        size = _batch_size(tuple(x for x, a in zip(args, self.in_axes, strict=True) if a == 0))
        order = self._order(size, cost)
        if order is not None:
            args = tuple(
                _rows(x, order) if a == 0 else x for x, a in zip(args, self.in_axes, strict=True)
            )
        starts = range(0, size, self._chunk(size))
        outs = [
            self._run_chunk(args, begin, size, k, len(starts)) for k, begin in enumerate(starts)
        ]
        out = (
            jax.tree.map(lambda *parts: jnp.concatenate(parts), *outs) if len(outs) > 1 else outs[0]
        )
        if order is not None:
            out = _rows(out, np.argsort(order))
        if self.keep_sharded:
            return out
        return jax.tree.map(_on_this_host, out)

    def _chunk(self, size: int) -> int:
        return min(self.chunk_size or size, size)

    def _rows_per_call(self, chunk: int) -> int:
        """A chunk's members padded to a multiple of the device count."""
        devices = self.mesh.devices.size
        return -(-chunk // devices) * devices

    def _order(self, size: int, cost) -> np.ndarray | None:
        if cost is None:
            return None
        cost = np.asarray(cost)
        if cost.shape != (size,):
            raise ValueError(f"`cost` is one number per member: shape ({size},), got {cost.shape}.")
        # The costliest first: the padding copies the last member, then the cheapest.
        return np.argsort(-cost, kind="stable")

    def _run_chunk(self, args, begin: int, size: int, k: int, chunks: int):
        """The results of members `begin : begin + chunk` (padded to the chunk's size
        rounded up to the device count: every chunk runs one program)."""
        chunk = self._chunk(size)
        end = min(begin + chunk, size)
        rows = self._rows_per_call(chunk)
        padded = tuple(
            _padded(jax.tree.map(lambda x: jnp.asarray(x)[begin:end], x), rows) if a == 0 else x
            for x, a in zip(args, self.in_axes, strict=True)
        )
        self._check_memory(padded, rows)
        started = time.perf_counter()
        out = jax.tree.map(lambda x: x[: end - begin], self.program(padded))
        if self.progress:
            jax.block_until_ready(out)
            print(
                f"chunk {k + 1}/{chunks}: members {begin}-{end - 1} of {size} "
                f"in {time.perf_counter() - started:.2f} s",
                flush=True,
            )
        return out

    def _check_memory(self, padded, rows: int):
        """Refuse, naming a chunk size that fits, a chunk whose program needs more memory
        on a device than it has (`memory_limit`, else what the device reports). The
        program is compiled here, once: the call that follows reuses it."""
        limit = self.memory_limit or _reported_memory(self.mesh)
        if limit is None or any(isinstance(x, Tracer) for x in jax.tree.leaves(padded)):
            return
        needed = self._memory_needed(padded)
        if needed <= limit:
            return
        devices = self.mesh.devices.size
        per_member = needed / (rows // devices)
        fits = int(limit // per_member) * devices
        advice = (
            f"vmap_over_devices(..., chunk_size={fits}) would fit"
            if fits
            else "not even one member per device fits: make the members smaller (fewer "
            "saved times, a shorter horizon)"
        )
        raise MemoryError(
            f"a chunk of {rows} members needs {needed / 2**20:.1f} MiB on each of the "
            f"{devices} device(s) (about {per_member / 2**20:.2f} MiB a member), more than "
            f"the {limit / 2**20:.1f} MiB each has; {advice}."
        )

    def _memory_needed(self, padded) -> int:
        """The bytes the program of `padded` needs on a device, from its compiled memory
        analysis; once per argument signature (a batch's every chunk shares one)."""
        arrays, static = eqx.partition(padded, eqx.is_array)
        key = (
            jax.tree.structure(padded),
            tuple((x.shape, x.dtype) for x in jax.tree.leaves(arrays)),
            static,
        )
        if key not in self._memory:
            # `filter_jit`'s wrapper lowers as `jax.jit`'s does; its type hides `lower`.
            lowered = self.program.lower(padded)  # pyright: ignore[reportFunctionMemberAccess]
            memory = lowered.lowered.compile().memory_analysis()
            self._memory[key] = (
                memory.argument_size_in_bytes + memory.output_size_in_bytes
                + memory.temp_size_in_bytes - memory.alias_size_in_bytes
            )  # fmt: skip
        return self._memory[key]

    def lockstep(self, steps, *, cost=None) -> Lockstep:
        r"""What lockstep costs this batch's layout, for the members' step counts.

        **Arguments:**

        - `steps`: each member's own steps (e.g. a solve's `stats["num_steps"]`), in the
          batch's order.
        - `cost`: the predicted cost the batch is (or would be) called with, if any.

        **Returns:**

        A `Lockstep`: the steps each member's share ran, the steps it needed, and the
        overhead $\ge 1$.
        """
        needed = np.asarray(steps, dtype=float)
        size, devices = needed.shape[0], self.mesh.devices.size
        order = self._order(size, cost)
        order = np.arange(size) if order is None else order
        chunk = self._chunk(size)
        rows = self._rows_per_call(chunk)
        taken, work = np.empty(size), 0.0
        for begin in range(0, size, chunk):
            members = order[begin : begin + chunk]
            padded = np.concatenate([members, np.repeat(members[-1:], rows - members.size)])
            for share in padded.reshape(devices, -1):
                slowest = needed[share].max()
                work += share.size * slowest
                taken[share] = slowest
        return Lockstep(taken, needed, work / needed.sum())


def vmap_over_devices(
    fn: Callable,
    *,
    in_axes: int | tuple[int | None, ...] = 0,
    mesh: Mesh | None = None,
    keep_sharded: bool = False,
    chunk_size: int | None = None,
    progress: bool = False,
    memory_limit: int | None = None,
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
    - `mesh`: a one-axis `jax.sharding.Mesh`; default, every device JAX sees: this
      process's, and under `jax.distributed` every process's, each process giving the
      same arguments and getting the whole results back.
    - `keep_sharded`: leave the results on the devices, sharded along the batch (for a
      further sharded computation), instead of gathering them on this process's first
      device.
    - `chunk_size`: run the batch `chunk_size` members at a time, one chunk after the
      other (all chunks one program): for a batch larger than the devices' memory, for
      progress along a long batch, and with `cost=` to bound the lockstep within a device.
    - `progress`: print each chunk's members and time as it ends.
    - `memory_limit`: the bytes a device may use for one chunk; default, the free memory
      the devices report (GPUs and TPUs; a CPU reports none, and is not checked). A chunk
      whose compiled program needs more raises `MemoryError` naming a `chunk_size` that
      fits, before it runs.

    **Returns:**

    A `DeviceBatch`: called on the batched arguments, the results of `jax.vmap(fn)` on
    one device, to rounding.
    """
    if mesh is None:
        mesh = Mesh(np.array(jax.devices()), (_AXIS,))
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
    if chunk_size is not None and chunk_size < 1:
        raise ValueError(f"`chunk_size` is a number of members, at least 1; got {chunk_size}.")
    return DeviceBatch(fn, mesh, keep_sharded, axes, chunk_size, progress, memory_limit)
