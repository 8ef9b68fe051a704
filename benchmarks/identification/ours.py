"""bundledyn's side of the identification benchmark: the nominal scene of a data set, what
is fitted (each fitted body's ten inertial parameters), the gauge, and one fit."""

import time

from benchmarks.identification.records import truth_system


class Bundledyn:
    """bundledyn's side of one data set: the nominal scene, what is fitted, the gauge."""

    def __init__(self, case, P_nominal):
        import jax.numpy as jnp

        from bundledyn import identify

        self.case = case
        self.compile_seconds = 0.0  # JAX's compiling in every fit of this data set so far
        self.truth = truth_system(case)
        self.index = [self.truth.names.index(b) for b in case.bodies]
        self.parameters = self._parameters(P_nominal)
        if case.gauge == "mass":
            mass = float(jnp.sum(self.truth.pseudo_inertias()[:, 3, 3]))
            self.gauge = identify.KnownMass(mass)
        else:
            self.gauge = identify.MeasuredInputs()

    def _parameters(self, P_fitted):
        """The fitted bodies free, at the pseudo-inertias `P_fitted` `(k, 4, 4)`."""
        import jax.numpy as jnp

        import bundledyn as bd
        from bundledyn import identify

        P = self.truth.pseudo_inertias().at[jnp.array(self.index)].set(jnp.asarray(P_fitted))
        system = self.truth.with_pseudo_inertias(P)
        if self.case.floating:
            scene = bd.Scene(system)
        else:
            scene = bd.Scene(system, [bd.Gravity()], base=bd.PrescribedBase.fixed())
        return identify.Parameters(scene, bodies=self.case.bodies)

    def cost_at(self, record, P) -> float:
        """The fit's merit ½‖r‖² + ½‖c‖² with the fitted bodies at `P`, the windows started
        from the measured states (its first cost, without a warm start)."""
        from bundledyn import identify

        result = identify.fit(
            self._parameters(P), record.measurements, inputs=record.inputs, gauge=self.gauge,
            warm_start=False, max_steps=1,
        )  # fmt: skip
        self.compile_seconds += result.stats["compile_seconds"]
        return float(result.costs[0])

    def fit(self, record):
        import numpy as np

        from bundledyn import identify

        begin = time.perf_counter()
        result = identify.fit(
            self.parameters, record.measurements, inputs=record.inputs, gauge=self.gauge
        )
        seconds = time.perf_counter() - begin
        self.compile_seconds += result.stats["compile_seconds"]
        P = np.asarray(result.scene.system.pseudo_inertias())[self.index]
        ident = result.identifiability
        return {
            "P": P,
            "seconds": seconds,
            "evaluations": result.stats["evaluations"],
            "trials": result.stats["trials"],
            "window_solves": result.stats["window_solves"],
            "steps": result.stats["steps"],
            "converged": bool(result.stats["converged"]),
            **{
                key: result.stats[key]
                for key in ("compile_seconds", "jacobian_seconds", "solve_seconds", "start_seconds")
            },
            "noise_scale": float(ident.noise_scale),
            "undetermined": list(ident.undetermined),
        }
