"""Is a model an acceptable mechanical model? Seed 004's invariance theorems as computations.

Static checks use the metric alone and run under jit and vmap over shapes:

- `galilean_conditions(system, q)`: the residuals of Theorem 2.2 (a), (b), (c).
- `rigid_structure(system, q)`: Theorem 2.3's $m$, $c_s$, $l_s$ and its three properties.
- `galilean_invariance(system, key, n)`: both on `n` sampled shapes in one compiled call,
  returned as a readable `InvarianceReport`.
- `boost_terms(...)`: the frame terms of (2.9)–(2.10) in a boosted frame, as accelerations.
- `curvature_by_holonomy(system, q, eps)`: the curvature from small horizontal loops.

Dynamic checks simulate one motion seen from two frames:

- `boost_discrepancy`: Galilean invariance (Theorem 2.2) under a boost.
- `gravity_discrepancy`: the elimination of gravity in a falling frame (Theorem 3.4).

Counter-examples, systems that break the conditions on purpose: `anisotropic_mass` (a),
`shape_dependent_mass` and `drifting_centre` (b), `translational_curvature` (c), and (b)
away from its symmetric shape.
"""

from ._checks._conditions import (
    GalileanConditions,
    RigidStructure,
    boost_terms,
    galilean_conditions,
    inertial_coupling,
    rigid_structure,
)
from ._checks._counterexamples import (
    anisotropic_mass,
    drifting_centre,
    shape_dependent_mass,
    translational_curvature,
)
from ._checks._dynamic import Discrepancy, boost_discrepancy, gravity_discrepancy
from ._checks._report import InvarianceReport, galilean_invariance
from ._holonomy import curvature_by_holonomy

__all__ = [
    "Discrepancy",
    "GalileanConditions",
    "InvarianceReport",
    "RigidStructure",
    "anisotropic_mass",
    "boost_discrepancy",
    "boost_terms",
    "curvature_by_holonomy",
    "drifting_centre",
    "galilean_conditions",
    "galilean_invariance",
    "gravity_discrepancy",
    "inertial_coupling",
    "rigid_structure",
    "shape_dependent_mass",
    "translational_curvature",
]
