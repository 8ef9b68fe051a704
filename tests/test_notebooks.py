"""The notebooks run top to bottom, and are committed with their outputs, figures as images."""

import ast
import copy
import os
import pathlib
import re

import nbformat
import pytest
from IPython.core.inputtransformer2 import TransformerManager
from nbclient import NotebookClient

FOLDER = pathlib.Path(__file__).resolve().parents[1] / "notebooks"
NOTEBOOKS = sorted(p.name for p in FOLDER.glob("*.ipynb"))
# Notebooks whose time goes into running a fit, not into compiling: their kernels compile
# with XLA's full optimisation (the suite's default skips it; see conftest.py).
RUN_BOUND = {"04_identification.ipynb"}

# What a cell's stored output must hold when the cell draws.
IMAGE_TYPES = frozenset({"image/png", "image/svg+xml", "image/gif", "image/jpeg"})
# Calls that draw, by the called name (an attribute's or a function's): matplotlib's figure
# and axes methods, bundledyn.viz's makers besides its `plot_*`, IPython's image displays,
# and writing a figure to a file (which shows nothing unless the cell displays it too).
# fmt: off
DRAWING_CALLS = frozenset({
    # matplotlib: a canvas, the axes' plotting methods, writing a file
    "subplots", "add_subplot", "add_axes", "savefig",
    "plot", "semilogx", "semilogy", "loglog", "scatter", "errorbar", "fill_between", "stem",
    "bar", "barh", "hist", "hist2d", "boxplot", "violinplot", "pie", "axhline", "axvline",
    "imshow", "matshow", "pcolormesh", "contour", "contourf", "quiver", "plot_surface",
    # bundledyn.viz (its `plot_*` count by their prefix), IPython's pictures
    "new_figure", "save_figure", "animate", "Image", "SVG",
})
# fmt: on
# pyplot calls that draw nothing: every other `plt.<name>(...)` counts as drawing.
PYPLOT_QUIET = frozenset({"close", "ioff", "ion", "rc", "rcdefaults", "switch_backend"})


def _calls(node):
    """The calls `node` makes when it runs: not those inside the functions it defines."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        if isinstance(child, ast.Call):
            yield child
        yield from _calls(child)


def _draws(call: ast.Call, drawers: set[str]) -> bool:
    """Whether `call` draws: a known drawing name, any `plot_*`, pyplot, or a drawing helper."""
    func = call.func
    name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
    owner = getattr(func.value, "id", "") if isinstance(func, ast.Attribute) else ""
    on_pyplot = owner == "plt" and name not in PYPLOT_QUIET
    return name in DRAWING_CALLS or name.startswith("plot_") or name in drawers or on_pyplot


def _drawing_helpers(tree, drawers: set[str]) -> set[str]:
    """`drawers` and the names of the functions `tree` defines whose bodies draw."""
    defined = [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)]
    found = set(drawers)
    while True:  # to a fixed point: a helper may draw by calling another one
        more = {f.name for f in defined if any(_draws(call, found) for call in _calls(f))}
        if more <= found:
            return found
        found |= more


def drawing_cells(book) -> list[int]:
    """Indices of the code cells that draw when they run, read from their source."""
    transform = TransformerManager().transform_cell  # magics and shell escapes to Python
    drawers: set[str] = set()  # functions defined in earlier cells that draw when called
    found = []
    for index, cell in enumerate(book.cells):
        if cell.cell_type != "code":
            continue
        tree = ast.parse(transform(cell.source))
        if any(_draws(call, drawers) for call in _calls(tree)):
            found.append(index)
        drawers = _drawing_helpers(tree, drawers)
    return found


def _is_image(output) -> bool:
    return bool(IMAGE_TYPES & set(output.get("data", {})))


def stores_image(cell) -> bool:
    """Whether a code cell's stored outputs hold a rendered picture."""
    return any(_is_image(output) for output in cell.outputs)


def cells_missing_images(book) -> list[int]:
    """Indices of the cells that draw but store no picture: cleared, or never displayed."""
    return [i for i in drawing_cells(book) if not stores_image(book.cells[i])]


def _read(name):
    return nbformat.read(FOLDER / name, as_version=4)


def test_readme_lists_every_notebook():
    """The README's links and the folder agree: no notebook unlisted, no dead link."""
    readme = (FOLDER.parent / "README.md").read_text()
    linked = set(re.findall(r"notebooks/([\w.-]+\.ipynb)", readme))
    assert linked == set(NOTEBOOKS)


DRAWING = {
    "pyplot": "import matplotlib.pyplot as plt\nplt.plot([0, 1])",
    "axes": "ax.loglog(r, error)",
    "axes in a loop": "for k in range(2):\n    ax[k].plot(t, q[:, k])",
    "figure to a file only": "fig.savefig('motion.png')",
    "viz": "viz.plot_drift(traj)",
    "viz to a file": "bd.viz.plot_motion(traj, path='motion.png')",
    "viz canvas": "fig = viz.new_figure(4, 3)\nfig.subplots().semilogy(t, e)",
    "animation": "viz.animate(traj, 'cat.gif')",
    "image display": "display(Image(filename='cat.gif'))",
    "displayed figure": "display(viz.plot_work_precision(series))",
}
NOT_DRAWING = {
    "imports": "%matplotlib inline\nimport jax\n\nfrom bundledyn import viz",
    "display imports": "import matplotlib.pyplot as plt\nfrom IPython.display import Image, display",
    "drawing in words": "# ax.plot(t, q) would draw\nprint('plt.plot(t, q) draws')",
    "a definition": "def show(ax):\n    ax.plot([0, 1])",
    "computation": "traj = bd.simulate(scene, state, 1.0)\nprint(traj.energy())",
    "pyplot housekeeping": "plt.close('all')",
    "shell": "!ls notebooks",
}


def _book(*sources):
    """A notebook of code cells with `sources` and no outputs."""
    return nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(s) for s in sources])


def _without_images(book, index, cleared):
    """A copy of `book` whose cell `index` lost its outputs (`cleared`) or only its pictures."""
    book = copy.deepcopy(book)
    cell = book.cells[index]
    cell.outputs = [] if cleared else [o for o in cell.outputs if not _is_image(o)]
    return book


@pytest.mark.parametrize("name", NOTEBOOKS)
def test_drawing_cells_store_images(name):
    """Every cell that draws holds its rendered picture in the committed notebook."""
    book = _read(name)
    missing = [book.cells[i].source.splitlines()[0] for i in cells_missing_images(book)]
    assert not missing, f"cells that draw but store no image: run and save them: {missing}"


@pytest.mark.parametrize("name", NOTEBOOKS)
def test_every_stored_image_is_seen_drawing(name):
    """Each notebook shows figures, and the check recognises how every one of them is drawn."""
    book = _read(name)
    pictured = [i for i, c in enumerate(book.cells) if c.cell_type == "code" and stores_image(c)]
    assert pictured, "a notebook with no figure"
    unseen = sorted(set(pictured) - set(drawing_cells(book)))
    assert not unseen, f"cells {unseen} draw in a way DRAWING_CALLS does not know"


@pytest.mark.parametrize("cleared", [True, False], ids=["output cleared", "image removed"])
@pytest.mark.parametrize("name", NOTEBOOKS)
def test_check_fails_a_committed_cell_without_its_image(name, cleared):
    """Each drawing cell of the committed notebooks fails the check once its picture is gone."""
    book = _read(name)
    drawing = drawing_cells(book)
    assert drawing, "nothing to take the picture from"
    for index in drawing:
        assert index in cells_missing_images(_without_images(book, index, cleared))


@pytest.mark.parametrize("source", DRAWING.values(), ids=DRAWING.keys())
def test_check_fails_a_drawing_cell_without_an_image(source):
    assert cells_missing_images(_book(source)) == [0]


@pytest.mark.parametrize("source", DRAWING.values(), ids=DRAWING.keys())
def test_check_passes_a_drawing_cell_with_its_image(source):
    book = _book(source)
    picture = {"image/png": "iVBORw0KGgo=", "text/plain": "<Figure size 400x300 with 1 Axes>"}
    book.cells[0].outputs = [nbformat.v4.new_output("display_data", data=picture)]
    assert cells_missing_images(book) == []


@pytest.mark.parametrize("source", NOT_DRAWING.values(), ids=NOT_DRAWING.keys())
def test_check_ignores_cells_that_do_not_draw(source):
    assert drawing_cells(_book(source)) == []


def test_a_drawing_helper_draws_where_it_is_called():
    """A function that draws makes the cells that call it draw, not the cell defining it."""
    book = _book(
        "def show(ax):\n    ax.plot([0, 1])",
        "def both(axes):\n    for ax in axes:\n        show(ax)",
        "x = 1",
        "both(axes)",
    )
    assert drawing_cells(book) == [3]


@pytest.mark.parametrize("name", NOTEBOOKS)
def test_committed_with_outputs(name):
    book = nbformat.read(FOLDER / name, as_version=4)
    code = [c for c in book.cells if c.cell_type == "code"]
    counts = [c.execution_count for c in code]
    assert counts == list(range(1, len(code) + 1)), "run it top to bottom and save the outputs"
    assert code[-1].outputs and not any(o.output_type == "error" for c in code for o in c.outputs)


@pytest.mark.parametrize("name", NOTEBOOKS)
def test_figures_are_stored_as_images(name):
    """Every figure is committed as a picture, not as its `<Figure ...>` text."""
    book = nbformat.read(FOLDER / name, as_version=4)
    outputs = [o for c in book.cells if c.cell_type == "code" for o in c.outputs]
    data = [o.get("data", {}) for o in outputs]
    as_text = [d for d in data if str(d.get("text/plain", "")).startswith("<Figure")]
    assert all("image/png" in d for d in as_text), "figures kept as text: add %matplotlib inline"


@pytest.mark.slow  # executes every notebook: minutes; the stored outputs are checked everyday
@pytest.mark.parametrize("name", NOTEBOOKS)
def test_runs_top_to_bottom(name):
    book = nbformat.read(FOLDER / name, as_version=4)
    # The kernel imports this checkout's bundledyn, as the tests do.
    env = dict(
        os.environ,
        PYTHONPATH=os.pathsep.join([str(FOLDER.parent), os.environ.get("PYTHONPATH", "")]),
    )
    if name in RUN_BOUND:
        env["JAX_DISABLE_MOST_OPTIMIZATIONS"] = "0"
    client = NotebookClient(
        book, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(FOLDER)}}
    )
    client.execute(env=env)  # raises CellExecutionError on the first failing cell
