"""The package's import graph: no circle of modules, ``sb3_saeir.common`` imports only ``sb3_saeir.common``, and the
env layer (``sb3_saeir.common.vec_env``) reaches none of the algorithm's modules.

Every ``sb3_saeir/**/*.py`` is parsed with :mod:`ast`; every ``import`` / ``from ... import`` of a ``sb3_saeir``
module counts, at module level or inside a function (relative imports resolved). ``from pkg import name`` is an
import of ``pkg.name`` when that is a module of the package, else of ``pkg``. The implicit import of parent packages
(``import a.b.c`` first runs ``a/__init__.py``) is left out, and so is a module importing itself.
"""

from __future__ import annotations

import ast
import subprocess
import sys
import textwrap
from pathlib import Path

import sb3_saeir

PACKAGE = "sb3_saeir"
PACKAGE_ROOT = Path(sb3_saeir.__file__).parent
# Every module under this package may import only modules under it.
SELF_CONTAINED = "sb3_saeir.common"
# The env layer, and the algorithm's modules it must not reach, directly or through other modules (package prefixes).
ENV_LAYER = "sb3_saeir.common.vec_env"
ALGORITHM_MODULES = (
    "sb3_saeir.common.policies",
    "sb3_saeir.common.buffers",
    "sb3_saeir.common.checks",
    "sb3_saeir.common.method_arguments",
    "sb3_saeir.mappo",
    "sb3_saeir.saeir_ppo",
    "sb3_saeir.intrinsic",
    "sb3_saeir.config",
    "sb3_saeir.command_line",
    "sb3_saeir.run",
    "sb3_saeir.run.output",
    "sb3_saeir.run.record",
    "sb3_saeir.experiment",
    "sb3_saeir.train",
    "sb3_saeir.benchmark",
    "sb3_saeir.zoo",
)

# The run wing (a run in the folder it owns) stands above the experiment and below the commands: the modules under it
# reach none of the commands, the layers under it import nothing of it, and its lock is its own.
RUN_WING = "sb3_saeir.run"
COMMANDS = (
    "sb3_saeir.train",
    "sb3_saeir.benchmark",
    "sb3_saeir.zoo",
    "sb3_saeir.enjoy",
    "sb3_saeir.command_line",
    "sb3_saeir.hyperparams_opt",
)
BELOW_THE_RUN_WING = (
    "sb3_saeir.common",
    "sb3_saeir.envs",
    "sb3_saeir.mappo",
    "sb3_saeir.saeir_ppo",
    "sb3_saeir.intrinsic",
    "sb3_saeir.config",
    "sb3_saeir.experiment",
    "sb3_saeir.evaluation",
)
RUN_LOCK_CLASS = "RunFolderLock"

Graph = dict[str, set[str]]


def module_name(path: Path, root: Path = PACKAGE_ROOT) -> str:
    """The dotted name of a source file (``sb3_saeir/common/vec_env.py`` -> ``sb3_saeir.common.vec_env``).

    :param path: the file
    :param root: the package's folder
    """
    parts = [root.name, *path.relative_to(root).with_suffix("").parts]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def package_sources(root: Path = PACKAGE_ROOT) -> dict[str, Path]:
    """Every module of the package, by dotted name.

    :param root: the package's folder
    """
    return {module_name(path, root): path for path in sorted(root.rglob("*.py"))}


def from_import_base(node: ast.ImportFrom, module: str, is_package: bool) -> str:
    """The absolute module a ``from ... import`` statement imports from.

    :param node: the statement
    :param module: the dotted name of the module holding it
    :param is_package: whether that module is a package's ``__init__``
    """
    if node.level == 0:
        return node.module or ""
    anchor = module.split(".")
    if not is_package:
        anchor = anchor[:-1]
    anchor = anchor[: len(anchor) - (node.level - 1)]
    return ".".join([*anchor, node.module] if node.module else anchor)


def is_in_package(name: str, package: str = PACKAGE) -> bool:
    """Whether a dotted name is the package or one of its modules.

    :param name: the dotted name
    :param package: the package
    """
    return name == package or name.startswith(package + ".")


def imports_of(source: str, module: str, is_package: bool, known_modules: set[str]) -> set[str]:
    """The package modules one source file imports, anywhere in the file.

    :param source: the file's text
    :param module: its dotted name
    :param is_package: whether it is a package's ``__init__``
    :param known_modules: every module of the package (``from pkg import name`` counts as ``pkg.name`` when listed)
    :return: the imported modules, the module itself left out
    """
    imported: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            imported.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = from_import_base(node, module, is_package)
            for alias in node.names:
                submodule = f"{base}.{alias.name}"
                imported.add(submodule if submodule in known_modules else base)
    return {name for name in imported if is_in_package(name) and name != module}


def import_graph(root: Path = PACKAGE_ROOT) -> Graph:
    """Module -> the package modules it imports, for every module of the package.

    :param root: the package's folder
    """
    sources = package_sources(root)
    known = set(sources)
    return {
        module: imports_of(path.read_text(encoding="utf-8"), module, path.name == "__init__.py", known)
        for module, path in sources.items()
    }


def find_cycle(graph: Graph) -> list[str] | None:
    """One circle of the graph, or ``None`` when it has none.

    :param graph: module -> the modules it imports
    :return: the modules of the circle, the first one repeated at the end (``["a", "b", "a"]``)
    """
    done: set[str] = set()

    def visit(node: str, path: list[str]) -> list[str] | None:
        if node in path:
            return [*path[path.index(node) :], node]
        if node in done:
            return None
        for target in sorted(graph.get(node, ())):
            cycle = visit(target, [*path, node])
            if cycle is not None:
                return cycle
        done.add(node)
        return None

    for start in sorted(graph):
        cycle = visit(start, [])
        if cycle is not None:
            return cycle
    return None


def outside_imports(graph: Graph, package: str) -> dict[str, set[str]]:
    """The imports from modules under ``package`` of modules outside it.

    :param graph: module -> the modules it imports
    :param package: the dotted name of the subpackage
    :return: module -> the outside modules it imports, only for modules that import one
    """
    outside = {
        module: {target for target in targets if not is_in_package(target, package)}
        for module, targets in graph.items()
        if is_in_package(module, package)
    }
    return {module: targets for module, targets in outside.items() if targets}


def forbidden_paths(graph: Graph, package: str, forbidden: tuple[str, ...]) -> dict[str, list[str]]:
    """The import chains from modules under ``package`` to modules under any of ``forbidden``.

    :param graph: module -> the modules it imports
    :param package: the dotted name of the subpackage whose imports are checked
    :param forbidden: dotted names of the modules (and packages) it must not reach
    :return: module of ``package`` -> the shortest chain of imports from it to a forbidden module (ending with that
        module), only for modules that reach one
    """
    found: dict[str, list[str]] = {}
    for start in sorted(module for module in graph if is_in_package(module, package)):
        seen, queue = {start}, [[start]]
        while queue:  # breadth first: the shortest chain
            path = queue.pop(0)
            if any(is_in_package(path[-1], name) for name in forbidden):
                found[start] = path
                break
            for target in sorted(graph.get(path[-1], ())):
                if target not in seen:
                    seen.add(target)
                    queue.append([*path, target])
    return found


def test_graph_sees_every_kind_of_import() -> None:
    source = textwrap.dedent(
        """
        import sb3_saeir.a
        from . import b
        from .c import name
        def f():
            from sb3_saeir.d import e
        import numpy
        """
    )
    known = {"sb3_saeir.a", "sb3_saeir.pkg", "sb3_saeir.pkg.b", "sb3_saeir.pkg.c", "sb3_saeir.d", "sb3_saeir.d.e"}
    imported = imports_of(source, "sb3_saeir.pkg.x", is_package=False, known_modules=known)
    assert imported == {"sb3_saeir.a", "sb3_saeir.pkg.b", "sb3_saeir.pkg.c", "sb3_saeir.d.e"}


def test_find_cycle_finds_a_two_module_cycle() -> None:
    graph = {"sb3_saeir.a": {"sb3_saeir.b"}, "sb3_saeir.b": {"sb3_saeir.a"}, "sb3_saeir.c": {"sb3_saeir.a"}}
    assert find_cycle(graph) == ["sb3_saeir.a", "sb3_saeir.b", "sb3_saeir.a"]
    assert find_cycle({"sb3_saeir.a": {"sb3_saeir.b"}, "sb3_saeir.b": set()}) is None


def test_package_has_no_import_cycle() -> None:
    cycle = find_cycle(import_graph())
    assert cycle is None, f"import circle: {' -> '.join(cycle or [])}"


def test_common_imports_only_common() -> None:
    outside = outside_imports(import_graph(), SELF_CONTAINED)
    assert not outside, f"{SELF_CONTAINED} imports modules outside it: {outside}"


def test_forbidden_paths_follow_imports_through_other_modules() -> None:
    graph = {
        "sb3_saeir.common.vec_env.a": {"sb3_saeir.common.utils"},
        "sb3_saeir.common.vec_env.b": {"sb3_saeir.common.registry"},
        "sb3_saeir.common.registry": {"sb3_saeir.mappo.mappo"},
        "sb3_saeir.common.utils": set(),
    }
    found = forbidden_paths(graph, "sb3_saeir.common.vec_env", ("sb3_saeir.mappo",))
    assert found == {
        "sb3_saeir.common.vec_env.b": ["sb3_saeir.common.vec_env.b", "sb3_saeir.common.registry", "sb3_saeir.mappo.mappo"]
    }
    assert forbidden_paths(graph, "sb3_saeir.common.vec_env", ("sb3_saeir.run",)) == {}


def test_env_layer_reaches_no_algorithm_module() -> None:
    graph = import_graph()
    assert any(is_in_package(module, ENV_LAYER) for module in graph), f"{ENV_LAYER} not found"
    found = forbidden_paths(graph, ENV_LAYER, ALGORITHM_MODULES)
    chains = {module: " -> ".join(path) for module, path in found.items()}
    assert not found, f"the env layer imports the algorithm's modules: {chains}"


def test_the_run_wing_reaches_no_command() -> None:
    reached = forbidden_paths(import_graph(), RUN_WING, COMMANDS)
    assert not reached, f"the run wing reaches command modules: {reached}"


def test_no_layer_below_the_run_wing_imports_it() -> None:
    graph = import_graph()
    below = {
        module: sorted(target for target in targets if is_in_package(target, RUN_WING))
        for module, targets in graph.items()
        if any(is_in_package(module, layer) for layer in BELOW_THE_RUN_WING)
    }
    assert not {module: targets for module, targets in below.items() if targets}


def names_used(source: str) -> set[str]:
    """Every name a source file imports or reads (``RunFolderLock``, ``lock.RunFolderLock``).

    :param source: the file's text
    """
    names: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.Name):
            names.add(node.id)
        elif isinstance(node, ast.Attribute):
            names.add(node.attr)
    return names


def test_names_used_sees_imports_and_attributes() -> None:
    assert {"RunFolderLock", "acquire"} <= names_used("from x import RunFolderLock\nRunFolderLock(p).acquire()")
    assert "RunFolderLock" in names_used("import sb3_saeir.run.lock as lock\nlock.RunFolderLock(p)")


def test_only_the_run_wing_takes_a_run_folders_lock() -> None:
    """Callers hand a :class:`~sb3_saeir.run.folder.RunFolder` over; none locks a folder itself (catching
    ``RunFolderInUseError`` is no lock)."""
    takers = sorted(
        module
        for module, path in package_sources().items()
        if not is_in_package(module, RUN_WING) and RUN_LOCK_CLASS in names_used(path.read_text(encoding="utf-8"))
    )
    assert takers == []


def test_importing_common_alone_registers_the_packaged_tasks() -> None:
    # common does not import envs: the registration comes from sb3_saeir/__init__.py, run by any sb3_saeir import.
    code = "from sb3_saeir.common.registry import list_tasks; print(' '.join(list_tasks()))"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert {"cn-sparse-n3", "cn-sparse-n4"} <= set(result.stdout.split())
