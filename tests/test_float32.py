"""float32, the precision JAX starts in: every shipped model imports, simulates as it does in
float64 (to float32's tolerance) and passes the invariance check; every shipped scene file
runs, the float64 tolerances it asks for raised to float32's with a warning that says so.

Each float32 part runs in a fresh interpreter, as a user's session without `enable_x64`
does: JAX does not support switching precision back and forth in one process (constants it
cached in one precision meet the other's)."""

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import bundledyn as bd

MODELS = sorted(p.name for p in bd.models.iterdir())
SCENES = sorted(p.name for p in bd.scenes.iterdir())

# The model's pose after 0.3 s from a generic state, at `simulate`'s default tolerances for
# the working precision, and its invariance report on 8 shapes.
_FINAL_POSE = """
import json, warnings
import jax, jax.numpy as jnp
import bundledyn as bd

def final_pose(name):
    # What the importer leaves out it says in warnings, checked in test_mujoco_import.py.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        scene = bd.load_scene(bd.models / name)
    d = scene.system.shape_dim
    xi = jnp.array([0.3, -0.2, 0.5, 0.1, 0.0, -0.1])
    qdot = 0.5 * jnp.cos(jnp.arange(d, dtype=float))
    state = bd.State(jnp.eye(4), jnp.full(d, 0.1), xi, qdot)
    return scene, bd.simulate(scene, state, 0.3).g[-1]
"""


def _in_float32(code: str):
    """Run `code` (after `_FINAL_POSE`'s definitions) in a fresh interpreter without
    `enable_x64`; return what it prints, read as JSON."""
    done = subprocess.run(
        [sys.executable, "-c", _FINAL_POSE + textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.splitlines()[-1])


@pytest.fixture(scope="module")
def float32_models():
    return _in_float32(
        f"""
        results = {{}}
        for name in {MODELS!r}:
            scene, pose = final_pose(name)
            report = bd.checks.galilean_invariance(scene.system, jax.random.key(0), n=8)
            dtypes = sorted({{str(leaf.dtype) for leaf in jax.tree.leaves(scene.system)}})
            results[name] = [pose.tolist(), str(pose.dtype), dtypes, bool(report.passed)]
        print(json.dumps(results))
        """
    )


@pytest.mark.slow  # every shipped model compiled twice, in float32 and in float64
@pytest.mark.xdist_group("float32_models")  # one worker runs the models' fixture once
@pytest.mark.parametrize("name", MODELS)
def test_a_shipped_model_imports_simulates_and_is_invariant_in_float32(float32_models, name):
    pose, dtype, system_dtypes, invariant = float32_models[name]
    assert dtype == "float32" and system_dtypes == ["float32"] and invariant
    namespace = {}
    exec(_FINAL_POSE, namespace)  # the same motion in float64 (this process), at 1e-8
    _, reference = namespace["final_pose"](name)
    np.testing.assert_allclose(np.asarray(pose), np.asarray(reference), rtol=0, atol=5e-3)


def test_float32_is_named_where_it_is_the_cause():
    refused = _in_float32(
        """
        scene, _ = final_pose("chain5.xml")
        try:
            bd.simulate(scene, bd.State(jnp.eye(4), jnp.zeros(scene.system.shape_dim)), 0.3,
                        rtol=1e-10, atol=1e-10)
        except ValueError as error:
            print(json.dumps(str(error)))
        """
    )
    assert "float32's rounding error" in refused and "enable_x64" in refused


@pytest.mark.slow  # every scene's programs compiled: half a minute
def test_every_shipped_scene_file_runs_in_float32():
    ran = _in_float32(
        f"""
        import numpy as np
        results = {{}}
        for name in {SCENES!r}:
            path = bd.scenes / name
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                if bd.is_gyroscope_file(path):
                    solved = bd.GyroscopeChainFile.load(path).solve().ys
                else:
                    solved = bd.SceneFile.load(path).simulate().g
            leaves = jax.tree.leaves(solved)
            results[name] = [
                sorted({{str(leaf.dtype) for leaf in leaves}}),
                all(bool(np.all(np.isfinite(np.asarray(leaf)))) for leaf in leaves),
                [str(w.message) for w in caught],
            ]
        print(json.dumps(results))
        """
    )
    assert set(ran) == set(SCENES)
    for name, (dtypes, finite, caught) in ran.items():
        assert dtypes == ["float32"] and finite, name
        assert any("cannot be met in float32; solving at 1.2e-05" in w for w in caught), name
