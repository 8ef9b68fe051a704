"""Hard cases, each with a stated bound: a battery to run on the shipped systems or a model.

Each case builds a system that has broken other simulators (their issue trackers record
the failures each case's docstring cites), runs it, and returns rows: what was measured,
the figure and its bound.

```python
import bundledyn as bd

bd.enable_x64()
report = bd.stress.battery()           # every case; `quick=True` for the suite's settings
print(report)                          # the table; report.passed, report.failed
scene = bd.load_scene("robot.xml", passive=True)   # with its springs
print(bd.stress.model_battery(scene, "robot.xml"))  # the cases that apply to a model
```

From the shell: `bundledyn stress` and `bundledyn stress MODEL` (exit status 1 on a failure).
"""

from ._stress._battery import (
    battery,
    free_motion,
    model_battery,
    springs_motion,
    springs_of,
    stiffest_period,
)
from ._stress._failures import advice, bad_values, float32
from ._stress._gradients import model_gradients, rigid_gradients
from ._stress._orbit import orbital_speed
from ._stress._ratios import (
    ball_turns,
    degenerate_stretch,
    folded_chain,
    mass_ratio,
    stiff_springs,
    thin_rod,
)
from ._stress._rigid import dzhanibekov, flip_interval, high_spin, long_horizon
from ._stress._row import StressReport, StressRow
from ._stress._variational import variational_long_run

__all__ = [
    "StressReport",
    "StressRow",
    "advice",
    "bad_values",
    "ball_turns",
    "battery",
    "degenerate_stretch",
    "dzhanibekov",
    "flip_interval",
    "float32",
    "folded_chain",
    "free_motion",
    "high_spin",
    "long_horizon",
    "mass_ratio",
    "model_battery",
    "model_gradients",
    "orbital_speed",
    "rigid_gradients",
    "springs_motion",
    "springs_of",
    "stiff_springs",
    "stiffest_period",
    "thin_rod",
    "variational_long_run",
]
