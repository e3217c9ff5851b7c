"""Imports in course_lib point down only (DESIGN.md, "Layers (imports point down only)").

Every module of course_lib is parsed with `ast`; every import, at module level or inside a function, `import x`
or `from x import y`, relative ones resolved, is an edge of the module graph.  Importing ``a.b.c`` also runs the
packages ``a`` and ``a.b`` (their ``__init__``), so those are edges too, except the importer's own packages.
Each module has a layer in ``LAYERS`` (bottom to top, as DESIGN.md's diagram); an import may point to a lower
layer, or to the same layer where it closes no loop.  A function-level import is counted like a module-level
one: it may be kept for import speed (jax, torch._dynamo), never to hide an edge.

Imports made at run time by name (``importlib.import_module``) are invisible to this test: ``DYNAMIC`` lists
the only modules allowed them, and what they import.
"""

from __future__ import annotations

import ast
from pathlib import Path

import course_lib

PACKAGE = Path(course_lib.__file__).resolve().parent

# Bottom to top.  Names are relative to course_lib ("course_lib" itself is the package's __init__).
LAYERS = (
    # 0  conventions, quaternions, bones; file bookkeeping, run modes, JSON results, training logs (no Motion)
    ("course_lib", "paths", "rotations", "skeleton", "checksums", "modes", "outputs", "manifest", "results", "history"),
    # 1  the Motion container
    ("motion",),
    # 2  generators; file I/O; pictures and plots; features <-> Motion
    ("synthetic", "synthetic.actions", "synthetic.body", "synthetic.ik", "synthetic.locomotion", "synthetic.noise",
     "synthetic.subjects", "bvh", "render", "plots", "representations"),
    # 3  windows, normalisation, saved clip files; the shared locomotion corpus; the realism report of a data
    #    set (it reads saved clips with datasets.load_motions; no generator imports it)
    ("datasets", "corpus", "synthetic.report"),
    # 4  one file per paper + baselines; the JAX ports
    ("models", "models.baselines", "models.contact_cleanup", "models.gmm_rnn", "models.hvrnn", "models.lstm_step",
     "models.moglow", "models.motion_matching", "models.refiner", "models.vae", "models.vae_lstm", "models.jax_moglow",
     "models.jax_vae", "jax_reference"),
    # 5  the fit loop and checkpoints; metrics, classifiers, FID/IS/C2ST, tables
    ("training", "evaluation", "evaluation.classifiers", "evaluation.contacts", "evaluation.distribution",
     "evaluation.freezing", "evaluation.metrics", "evaluation.perturb", "evaluation.tables"),
    # 6  MAP motion design, online control, denoising (paper B, sec. 5)
    ("control", "control.denoise", "control.design", "control.dropouts", "control.energy", "control.initial_state",
     "control.kinematics", "control.lbfgs", "control.lowpass", "control.online", "control.planting", "control.pso",
     "control.rnn_prior", "control.rollout", "control.spikes", "control.starts", "control.window"),
    # 7  one module per lesson
    ("experiments", "experiments.control", "experiments.gmm_rnn", "experiments.gmm_rnn_jitter", "experiments.hvrnn",
     "experiments.moglow", "experiments.vae_basics", "experiments.vae_lstm"),
    # 8  one protocol for all models; timings; the ONNX export of a trained model
    ("benchmark", "timings", "export"),
    # 9  the reproduction CLI; the exercises' answers
    ("reproduce", "solutions", "solutions.benchmark", "solutions.control", "solutions.data_lesson",
     "solutions.gmm_rnn", "solutions.hvrnn", "solutions.measures", "solutions.moglow", "solutions.vae_basics",
     "solutions.vae_lstm"),
)

# module -> what it imports by name at run time; each points down.  The evaluation package imports its classifier
# names lazily (PEP 562) so that `python -m course_lib.evaluation.classifiers` runs that module only once.
DYNAMIC = {
    "course_lib.evaluation": ("course_lib.evaluation.classifiers", "course_lib.evaluation.distribution"),
}


def _full(name: str) -> str:
    return name if name == "course_lib" else f"course_lib.{name}"


def layer_of() -> dict[str, int]:
    out = {}
    for i, names in enumerate(LAYERS):
        for name in names:
            assert _full(name) not in out, f"{name} is in LAYERS twice"
            out[_full(name)] = i
    return out


def modules() -> dict[str, Path]:
    """Every module of course_lib: dotted name -> file."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = ("course_lib",) + path.relative_to(PACKAGE).with_suffix("").parts
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _enclosing_function(tree: ast.Module) -> dict[ast.AST, str | None]:
    """Each import node -> the name of the function it sits in (None at module level)."""
    out = {}

    def walk(node, fn):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                out[child] = fn
            walk(child, child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else fn)

    walk(tree, None)
    return out


def import_edges(known: dict[str, Path]) -> list[tuple[str, str, str]]:
    """-> [(importer, imported, where)], imported a course_lib module; where: "file.py:line" (+ the function)."""
    edges, root = [], known["course_lib"].parent.parent
    for name, path in known.items():
        is_package = path.name == "__init__.py"
        tree = ast.parse(path.read_text(), str(path))
        for node, fn in _enclosing_function(tree).items():
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                base = node.module or ""
                if node.level:  # relative: from the importer's package, up level - 1
                    pkg = name.split(".") if is_package else name.split(".")[:-1]
                    pkg = pkg[:len(pkg) - (node.level - 1)]
                    base = ".".join(pkg + ([node.module] if node.module else []))
                # `from pkg import sub` imports the submodule; `from mod import obj` only mod
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
            where = f"{path.relative_to(root)}:{node.lineno}" + (f" (in {fn})" if fn else "")
            for target in targets:
                if not (target == "course_lib" or target.startswith("course_lib.")):
                    continue
                parts = target.split(".")
                for k in range(1, len(parts) + 1):  # the packages on the way run first
                    imported = ".".join(parts[:k])
                    own_package = name == imported or name.startswith(imported + ".")
                    if imported in known and not own_package:
                        edges.append((name, imported, where))
    return sorted(set(edges))


def cycles(edges) -> list[list[str]]:
    """The loops a depth-first search meets (one per back edge), each as [a, b, ..., a]."""
    graph = {}
    for a, b, _ in edges:
        graph.setdefault(a, set()).add(b)
    state, stack, found = {}, [], []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                found.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node)
    return found


def test_every_module_has_a_layer():
    layers, known = layer_of(), modules()
    missing = sorted(set(known) - set(layers))
    assert not missing, (f"modules without a layer: {missing}; add each to LAYERS in tests/test_import_layers.py, "
                         "at the level of DESIGN.md's diagram where it belongs")
    gone = sorted(set(layers) - set(known))
    assert not gone, f"LAYERS names modules that do not exist: {gone}"


def test_imports_point_down_only():
    layers, known = layer_of(), modules()
    edges = import_edges(known)
    assert len(edges) > 300, f"only {len(edges)} import edges found: the parser misses imports"
    up = [f"{a} (layer {layers[a]}) -> {b} (layer {layers[b]})  at {where}"
          for a, b, where in edges if layers.get(b, -1) > layers.get(a, 99)]
    assert not up, f"{len(up)} upward import(s):\n" + "\n".join(up)


def test_no_import_loops():
    found = cycles(import_edges(modules()))
    assert not found, f"{len(found)} import loop(s):\n" + "\n".join(" -> ".join(c) for c in found)


def test_reproduce_is_imported_by_no_module():
    """reproduce.py is the command line: nothing in the library depends on it."""
    users = sorted({f"{a} at {where}" for a, b, where in import_edges(modules()) if b == "course_lib.reproduce"})
    assert not users, "course_lib.reproduce is imported by: " + "; ".join(users)


def test_dynamic_imports_only_where_listed_and_pointing_down():
    layers, known = layer_of(), modules()
    found = set()
    for name, path in known.items():
        for node in ast.walk(ast.parse(path.read_text())):
            call = node.func if isinstance(node, ast.Call) else None
            if (isinstance(call, ast.Attribute) and call.attr == "import_module"
                    or isinstance(call, ast.Name) and call.id in ("__import__", "import_module")):
                found.add(name)
    assert found == set(DYNAMIC), f"modules that import by name at run time: {sorted(found)}; DYNAMIC lists " \
                                  f"{sorted(DYNAMIC)} (a new one must be listed with what it imports)"
    for name, targets in DYNAMIC.items():
        for target in targets:
            assert target in known and layers[target] <= layers[name], f"{name} imports {target} upward"


def test_the_checker_sees_function_level_relative_and_package_imports(tmp_path):
    """The parser on a made-up module: each form of import gives its edge, and a loop and an upward edge are
    reported."""
    pkg = tmp_path / "course_lib"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "low.py").write_text("from .sub import thing\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "thing.py").write_text("def f():\n    import course_lib.high\n")
    (pkg / "high.py").write_text("from course_lib import low\n")
    known = {}
    for path in sorted(pkg.rglob("*.py")):
        parts = ("course_lib",) + path.relative_to(pkg).with_suffix("").parts
        known[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    pairs = {(a, b) for a, b, _ in import_edges(known)}
    assert pairs == {("course_lib.low", "course_lib.sub"), ("course_lib.low", "course_lib.sub.thing"),
                     ("course_lib.sub.thing", "course_lib.high"), ("course_lib.high", "course_lib.low")}
    assert cycles(import_edges(known)) == [["course_lib.high", "course_lib.low", "course_lib.sub.thing",
                                            "course_lib.high"]]
