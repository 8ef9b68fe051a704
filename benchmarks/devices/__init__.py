"""Throughput of a batch over devices: `vmap_over_devices` on 1, 2 and 4 devices.

The speed benchmark's batch (part 3: 1 s rollouts of the 5-body chain from 1024 initial
states, each method at the setting where its largest error over the batch is MuJoCo RK4's
at dt = 1e-2, read from `results/speed.json`) run by `bd.vmap_over_devices` on 1, 2 and 4
devices, each count in a fresh worker process (XLA fixes its devices when it starts: on
the CPU, `--xla_force_host_platform_device_count`, on top of `bd.CPU_XLA_FLAGS`). In each
worker, timed in alternation with `mujoco.rollout` of the same batch on 2 threads (MuJoCo's
RK4 at dt = 1e-2): rollouts per second, the ratio to MuJoCo's, the lockstep overhead
(`DeviceBatch.lockstep`) and the largest difference of the final poses from one device's
`jax.vmap`. The report gives each count's scaling efficiency, its throughput over one
device's divided by the cores it can use (`min(devices, cores)`).

Usage, from the repository root (needs the `bench` extra for MuJoCo)::

    python -m benchmarks.devices                # writes results/devices.{md,json}
    python -m benchmarks.devices --quick        # 64 rollouts, 1 and 2 devices, 2 repeats
    python -m benchmarks.devices --report-only  # redraw the markdown from the JSON
"""

from benchmarks.devices.cli import main

__all__ = ["main"]
