"""bundledyn's side of the identification benchmark: the nominal scene of a data set, what
is fitted (each fitted body's ten inertial parameters), the gauge, and one fit."""

import time

from benchmarks.identification.records import truth_system


class Bundledyn:
    """bundledyn's side of one data set: the nominal scene, what is fitted, the gauge."""

    def __init__(self, case, P_nominal):
        import jax.numpy as jnp

        import bundledyn as bd
        from bundledyn import identify

        truth = truth_system(case)
        index = [truth.names.index(b) for b in case.bodies]
        P = truth.pseudo_inertias().at[jnp.array(index)].set(jnp.asarray(P_nominal))
        nominal = truth.with_pseudo_inertias(P)
        if case.floating:
            scene = bd.Scene(nominal)
        else:
            scene = bd.Scene(nominal, [bd.Gravity()], base=bd.PrescribedBase.fixed())
        self.index = index
        self.parameters = identify.Parameters(scene, bodies=case.bodies)
        if case.gauge == "mass":
            self.gauge = identify.KnownMass(float(jnp.sum(truth.pseudo_inertias()[:, 3, 3])))
        else:
            self.gauge = identify.MeasuredInputs()

    def fit(self, record):
        import numpy as np

        from bundledyn import identify

        begin = time.perf_counter()
        result = identify.fit(
            self.parameters, record.measurements, inputs=record.inputs, gauge=self.gauge
        )
        seconds = time.perf_counter() - begin
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
            "noise_scale": float(ident.noise_scale),
            "undetermined": list(ident.undetermined),
        }
