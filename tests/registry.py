"""Registries the test files share: the Lie-group solvers, the adjoints that differentiate a
solve, and one scene per scene mode. A test file takes its solvers, adjoints and mode
scenes from here rather than listing its own (its systems come from `systems.py`).

Equal modules compile to the same programs, so sharing these costs no compilation: with
`--dist loadfile` each file compiles its own programs in its worker anyway.
"""

from typing import NamedTuple

import diffrax
import jax.numpy as jnp
from systems import asymmetric_body, chain, chain3_state

import bundledyn as bd

# The explicit Lie-group Runge–Kutta(–Munthe-Kaas) solvers, lowest order first: each
# integrates on the group and differentiates its stages by a written-out reverse pass.
RK_SOLVERS = {
    "LieEuler": bd.LieEuler(),
    "RKMK4": bd.RKMK4(),
    "RKMK54": bd.RKMK54(),
    "RKMK87": bd.RKMK87(),
}
# `RKMK87` without its dense output: 13 stages a step instead of 14.
RKMK87_STEP_STAGES_ONLY = bd.RKMK87(dense_output=False)
# Every Lie-group solver: the Runge–Kutta family and the variational integrator.
SOLVERS = {**RK_SOLVERS, "VariationalMidpoint": bd.VariationalMidpoint()}

# The adjoints a gradient through `simulate` is checked with.
ADJOINTS = {
    # diffrax's reverse mode through the solve's steps: the reference for reverse mode.
    "checkpointed": diffrax.RecursiveCheckpointAdjoint(),
    # diffrax's forward-mode sensitivities: a derivation sharing nothing with either
    # reverse sweep.
    "forward": diffrax.ForwardMode(),
    # bundledyn's reverse sweep over the steps the forward solve kept (the default of its
    # Lie-group solvers), with the field's written-out reverse pass or autodiff's.
    "stored steps": bd.StoredStepsAdjoint(),
    "stored steps, autodiff field": bd.StoredStepsAdjoint(field_reverse="autodiff"),
}


class ModeScene(NamedTuple):
    """A scene of one mode, a state to start it from, the rows of the reference form
    (`[ξ̇; q̈]`, 6 + d) that the mode integrates, and whether its energy is conserved."""

    scene: bd.Scene
    state: bd.State
    rows: slice
    conserves_energy: bool


def _bend(t):
    return jnp.array([0.3 * jnp.sin(2.0 * t), -0.2 + 0.4 * t, 0.25 * jnp.cos(3.0 * t)])


def _deck(t):
    """A base heaving and rolling like a ship's deck."""
    twist = jnp.array([0.2 * jnp.sin(1.5 * t), 0.0, 0.0, 0.0, 0.0, 0.1 * jnp.sin(2.0 * t)])
    return bd.lie.se3_exp(twist)


_SPRING = bd.ShapeSpring(jnp.array([2.0, 1.5, 3.0]))
_CHAIN_STATE = chain3_state()
_RIGID_STATE = bd.State(jnp.eye(4), xi=jnp.array([0.4, -1.1, 0.7, 0.2, 0.1, -0.3]))
_ALL_ROWS = slice(None)

# One scene per built-in mode (a fixed base besides the moving one; the centre of mass's
# frame on a chain and on a rigid body), and a free shape seen from a falling frame. The
# prescribed shape and the moving deck do work on the system.
MODE_SCENES = {
    "free_shape": ModeScene(
        bd.Scene(chain(3), (bd.Gravity(), _SPRING)), _CHAIN_STATE, _ALL_ROWS, True
    ),
    "rigid_body": ModeScene(
        bd.Scene(asymmetric_body(), (bd.Gravity(),)), _RIGID_STATE, _ALL_ROWS, True
    ),
    "prescribed_shape": ModeScene(
        bd.Scene(chain(3), (bd.Gravity(),), shape=bd.Prescribed(_bend)),
        _CHAIN_STATE,
        slice(0, 6),
        False,
    ),
    "prescribed_base": ModeScene(
        bd.Scene(chain(3), (bd.Gravity(), _SPRING), base=bd.PrescribedBase(_deck)),
        _CHAIN_STATE,
        slice(6, None),
        False,
    ),
    "fixed_base": ModeScene(
        bd.Scene(chain(3), (bd.Gravity(), _SPRING), base=bd.PrescribedBase.fixed()),
        _CHAIN_STATE,
        slice(6, None),
        True,
    ),
    "centre_of_mass_chain": ModeScene(
        bd.Scene(chain(3), (bd.Gravity(), _SPRING), mode=bd.CentreOfMassMode()),
        _CHAIN_STATE,
        _ALL_ROWS,
        True,
    ),
    "centre_of_mass_rigid_body": ModeScene(
        bd.Scene(asymmetric_body(), (bd.Gravity(),), mode=bd.CentreOfMassMode()),
        _RIGID_STATE,
        _ALL_ROWS,
        True,
    ),
    "free_shape_falling_frame": ModeScene(
        bd.Scene(chain(3), (bd.Gravity(), _SPRING), frame=bd.FreeFalling(9.81)),
        _CHAIN_STATE,
        _ALL_ROWS,
        True,
    ),
}
