"""Every MJCF model that ships inside dm_control and gymnasium, imported as a MuJoCo user
would, and compared with MuJoCo.

Per model file (`models.py`; none written for bundledyn): whether it imports, and why not
where it is refused; where it does, with its springs, dampers and gravity as the model has
them (`Scene.from_mjcf(path, passive=True, gravity=True)`), from a state near its home pose
(`measure.start`):

1. the metric against MuJoCo's mass matrix (`mj_fullM`), relative (goal 1e-12);
2. one second of motion against MuJoCo's RK4 at dt = 1e-4 with contacts, limits, actuators
   and friction loss off, and whatever the import's warning says it leaves out (fluid
   forces, gravity compensation, the damping of ball joints) off too: the largest
   difference in `qpos` and `qvel` (goal 1e-9), bundledyn at rtol = atol = 1e-12; and
   against RK4 at an eighth of the step, which judges the goal where RK4's own error at
   1e-4 (the two MuJoCo runs' difference) exceeds it (small bodies, high frequencies);
3. the field's time over `mj_forward`'s at the same state, in alternation, and the solve's
   time beside MuJoCo's.

Usage, from the repository root (needs the `bench` extra, and the two packages' model
files: `pip install --no-deps dm_control gymnasium`)::

    python -m benchmarks.survey                # writes results/survey.{md,json}
    python -m benchmarks.survey --quick        # bundledyn's own two models, 0.1 s
    python -m benchmarks.survey --report-only  # redraw the markdown from the JSON
"""

from benchmarks.survey.cli import main

__all__ = ["main"]
