"""The models the survey imports: every MJCF model that ships inside dm_control (its
control suite, its locomotion walkers, its soccer player, the third-party ant) and
gymnasium (`gymnasium/envs/mujoco/assets/`), none written for bundledyn.

Only the packages' model files are read, so installing them without their dependencies is
enough: `pip install --no-deps dm_control gymnasium`."""

import importlib.util
import pathlib
from typing import NamedTuple

# (package, folder inside it, file patterns): the model files, not the fragments they
# include (dm_control's `suite/common/`, the fruit fly's builder, the dog's scene).
SOURCES = (
    ("dm_control", "suite", ("*.xml",)),
    (
        "dm_control",
        "locomotion/walkers/assets",
        (
            "humanoid_CMU_V2019.xml",
            "humanoid_CMU_V2020.xml",
            "rodent.xml",
            "dog_v2/dog.xml",
            "fruitfly_v2/fruitfly.xml",
            "jumping_ball/jumping_ball_with_head.xml",
        ),
    ),
    ("dm_control", "locomotion/soccer/assets", ("boxhead/boxhead.xml",)),
    ("dm_control", "third_party/ant", ("ant.xml",)),
    ("gymnasium", "envs/mujoco/assets", ("*.xml",)),
)


class ModelFile(NamedTuple):
    name: str  # "package/path inside the folder", e.g. "dm_control/suite/cheetah.xml"
    path: pathlib.Path


def package_folder(package: str) -> pathlib.Path | None:
    """Where an installed package's files are, without importing it (None if absent)."""
    spec = importlib.util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        return None
    return pathlib.Path(next(iter(spec.submodule_search_locations)))


def missing_packages() -> list[str]:
    return sorted({p for p, _, _ in SOURCES if package_folder(p) is None})


def model_files() -> list[ModelFile]:
    """Every model file of `SOURCES`, in their order (sorted within a folder)."""
    files = []
    for package, folder, patterns in SOURCES:
        root = package_folder(package)
        if root is None:
            continue
        for pattern in patterns:
            for path in sorted((root / folder).glob(pattern)):
                files.append(
                    ModelFile(f"{package}/{folder}/{path.relative_to(root / folder)}", path)
                )
    return files


QUICK = ("chain5.xml", "tree4.xml")  # a floating chain and a floating tree


def quick_files() -> list[ModelFile]:
    """Two of bundledyn's own MJCF models: the quick run needs neither package."""
    import bundledyn as bd

    paths = sorted(p for p in bd.models.iterdir() if p.name in QUICK)
    return [ModelFile(f"bundledyn/models/{p.name}", pathlib.Path(str(p))) for p in paths]
