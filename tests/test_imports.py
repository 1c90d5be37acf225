"""The package's import graph has no cycle — imports at module level and inside functions
alike (a function-local import is how a cycle hides) — and no module reaches into another's
private names."""
import ast
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGES = ("sphere_jax", "configs", "experiments")


def _modules():
    """Dotted name -> source file of every module of the project's packages."""
    out = {}
    for pkg in PACKAGES:
        for folder, _, files in os.walk(os.path.join(ROOT, pkg)):
            for f in files:
                if f.endswith(".py"):
                    rel = os.path.relpath(os.path.join(folder, f), ROOT)[:-3].split(os.sep)
                    name = ".".join(rel[:-1] if rel[-1] == "__init__" else rel)
                    out[name] = os.path.join(folder, f)
    return out


def import_graph(modules):
    """Module -> set of project modules it imports (``from a import b`` counts ``a.b`` when
    that is a module, else ``a``), and the private names imported from other modules."""
    graph, private = {}, []
    for name, path in modules.items():
        is_pkg = path.endswith("__init__.py")
        with open(path) as f:
            tree = ast.parse(f.read(), path)
        deps, bound = set(), {}          # bound: local name -> the project module it names
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                deps.update(a.name for a in node.names if a.name in modules)
                bound.update((a.asname, a.name) for a in node.names
                             if a.asname and a.name in modules)
            elif isinstance(node, ast.ImportFrom):
                if node.level:                                  # relative import
                    base = name.split(".") if is_pkg else name.split(".")[:-1]
                    base = base[:len(base) - node.level + 1]
                    src = ".".join(base + ([node.module] if node.module else []))
                else:
                    src = node.module
                for a in node.names:
                    full = f"{src}.{a.name}"
                    if full in modules:
                        deps.add(full)
                        bound[a.asname or a.name] = full
                    elif src in modules:
                        deps.add(src)
                        if a.name.startswith("_") and src != name:
                            private.append(f"{name} imports {src}.{a.name}")
        for node in ast.walk(tree):              # module._private, e.g. datasets._read_image
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in bound and node.attr.startswith("_")
                    and not node.attr.startswith("__")):
                private.append(f"{name} uses {bound[node.value.id]}.{node.attr}")
        deps.discard(name)
        graph[name] = deps
    return graph, private


def find_cycle(graph):
    """One import cycle as a list of modules, or None."""
    state, stack = {}, []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for d in sorted(graph.get(m, ())):
            if d in graph and state.get(d) == "open":
                return stack[stack.index(d):] + [d]
            if d in graph and d not in state:
                found = visit(d)
                if found:
                    return found
        stack.pop()
        state[m] = "done"
        return None

    for m in sorted(graph):
        if m not in state:
            found = visit(m)
            if found:
                return found
    return None


def _parents_excluded(graph):
    """A package's ``__init__`` importing its submodules is not a cycle with them: drop the
    edges from a submodule to its own parent packages (Python imports parents first)."""
    return {m: {d for d in deps if not m.startswith(d + ".")} for m, deps in graph.items()}


def test_no_import_cycle_in_the_project():
    graph, _ = import_graph(_modules())
    assert find_cycle(_parents_excluded(graph)) is None, find_cycle(_parents_excluded(graph))


def test_no_private_name_crosses_modules():
    _, private = import_graph(_modules())
    assert not private, private


def test_the_checker_finds_a_planted_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert find_cycle(graph) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


@pytest.mark.parametrize("source, expected", [
    ("def f():\n    from sphere_jax.bundles import inference\n",
     {"sphere_jax.bundles.inference"}),
    ("from sphere_jax.features import methods as m\n", {"sphere_jax.features.methods"}),
    ("import sphere_jax.paths\n", {"sphere_jax.paths"}),
])
def test_function_level_imports_are_seen(tmp_path, source, expected):
    path = tmp_path / "probe.py"
    path.write_text(source)
    modules = {k: v for k, v in _modules().items()}
    modules["probe"] = str(path)
    graph, _ = import_graph(modules)
    assert graph["probe"] == expected


def test_the_inference_api_does_not_import_open3d():
    """The JAX side (bundles, training's models, the spherical core) never needs open3d: importing
    it must not pull it in (it is a 400 MB library with a system dependency)."""
    import subprocess
    import sys
    code = ("import sys, sphere_jax.bundles.inference, sphere_jax.models, "
            "sphere_jax.spherical.fused; print('open3d' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


def _reachable(graph, roots):
    seen, todo = set(), list(roots)
    while todo:
        m = todo.pop()
        if m not in seen:
            seen.add(m)
            todo.extend(graph.get(m, ()))
    return seen


@pytest.mark.parametrize("layer, forbidden", [
    ("sphere_jax.registration", ("sphere_jax.eval", "sphere_jax.bundles", "sphere_jax.features")),
    ("sphere_jax.features", ("sphere_jax.eval",)),
    ("sphere_jax.align", ("sphere_jax.eval",)),
    ("sphere_jax.training", ("sphere_jax.eval", "sphere_jax.bundles.inference")),
])
def test_library_layers_do_not_reach_the_benchmarks(layer, forbidden):
    """Registration is a library the benchmark uses, never the other way round; descriptors
    come into it as arrays or functions, so it needs no trained bundle either."""
    graph, _ = import_graph(_modules())
    roots = [m for m in graph if m == layer or m.startswith(layer + ".")]
    reached = _reachable(graph, roots)
    bad = sorted(m for m in reached for f in forbidden if m == f or m.startswith(f + "."))
    assert roots and not bad, bad


def test_the_layer_check_sees_a_transitive_import():
    graph = {"sphere_jax.align": {"sphere_jax.x"}, "sphere_jax.x": {"sphere_jax.eval.pair_sets"}}
    assert "sphere_jax.eval.pair_sets" in _reachable(graph, ["sphere_jax.align"])


# sphere_jax's sub-packages and top-level modules, lowest first: each imports only from the
# layers below it (function-local imports included), never from its own layer's other units.
LAYERS = (
    ("checks",),
    ("files", "paths", "workdirs", "parallel", "spherical"),
    ("models", "data", "compile_cache"),
    ("registration",),
    ("bundles",),
    ("features",),
    ("training",),
    ("align",),                           # register: the pipeline a user calls
    ("eval",),
    ("",),                                # sphere_jax/__init__.py: the public functions
)


def _unit(module):
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def layering_violations(graph, layers=LAYERS):
    """``'a -> b'`` for every import of a unit from one at its own layer or above."""
    rank = {u: k for k, layer in enumerate(layers) for u in layer}
    bad = []
    for m, deps in graph.items():
        if m != "sphere_jax" and not m.startswith("sphere_jax."):
            continue
        for d in deps:
            if not d.startswith("sphere_jax") or _unit(d) == _unit(m):
                continue
            if rank[_unit(d)] >= rank[_unit(m)]:
                bad.append(f"{m} -> {d}")
    return sorted(bad)


def test_every_unit_has_a_layer_and_imports_only_below_it():
    graph, _ = import_graph(_modules())
    units = {_unit(m) for m in graph if m == "sphere_jax" or m.startswith("sphere_jax.")}
    placed = {u for layer in LAYERS for u in layer}
    assert units <= placed, f"units without a layer: {sorted(units - placed)}"
    assert layering_violations(graph) == []


def test_the_layer_rule_sees_an_upward_and_a_sideways_import():
    graph = {"sphere_jax.data.x": {"sphere_jax.features.y"},
             "sphere_jax.data.z": {"sphere_jax.models"},
             "sphere_jax.features.y": {"sphere_jax.data.x"}}
    assert layering_violations(graph) == ["sphere_jax.data.x -> sphere_jax.features.y",
                                          "sphere_jax.data.z -> sphere_jax.models"]
