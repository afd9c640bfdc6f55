"""The package's layout as its sub-package docstrings state it: who may import whom.

Reads every module's source (imports at module level, inside functions and under
``if TYPE_CHECKING:`` alike) rather than importing it, so a forbidden import or an import cycle is
found even on a code path no other test runs.
"""
from __future__ import annotations

import ast
import sys
from pathlib import Path


PACKAGE_DIR = Path(__file__).resolve().parents[1] / 'fall_predictor'
ROOT = 'fall_predictor'

#: Sub-package -> the sub-packages it may import at module level (itself and the package root
#: are always allowed), and those it may import only inside a function.
ALLOWED = {
    'monitor': (set(), set()),
    'contract': ({'monitor'}, set()),
    'profiles': ({'monitor'}, set()),
    'robot': ({'monitor', 'profiles'}, set()),
    'sim': ({'robot', 'monitor', 'profiles'}, set()),
    'data': ({'monitor', 'contract', 'profiles'}, {'sim'}),
    'learning': ({'monitor', 'data'}, set()),
    'ros': ({'monitor', 'contract', 'profiles', 'robot', 'sim', 'data', 'learning', 'cli', 'msg'},
            set()),
    'cli': ({'monitor', 'contract', 'data', 'profiles'}, {'robot', 'sim', 'learning', 'ros'}),
}
#: Third-party distributions the onboard code may use.
MONITOR_THIRD_PARTY = {'numpy', 'pinocchio'}
#: Top-level names of ROS 2 Python packages (rclpy, message packages, ament, launch).
ROS_MODULES = ('rclpy', 'rosidl', 'rcl_interfaces', 'builtin_interfaces', 'ament_index_python',
               'launch', 'rosgraph_msgs')


def is_ros_module(top: str) -> bool:
    return top.startswith(ROS_MODULES) or top.endswith(('_msgs', '_srvs', '_interfaces'))


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE_DIR.parent).with_suffix('').parts)
    if parts[-1] == '__init__':
        parts.pop()
    return '.'.join(parts)


def sub_package(module: str) -> str:
    """'fall_predictor.data.bagio' -> 'data'; 'fall_predictor.cli' -> 'cli'; root (and a module
    beside its __init__, such as 'fall_predictor.errors') -> ''."""
    parts = module.split('.')
    if len(parts) == 1:
        return ''
    if parts[1] == '__main__':
        return 'cli'
    if len(parts) == 2 and (PACKAGE_DIR / f'{parts[1]}.py').is_file():
        return ''                       # a module of the root (errors): part of the root
    return parts[1]


def imports(path: Path) -> list[tuple[str, bool]]:
    """(imported module, lazy) for every import statement of a module; lazy: not run when the
    module is imported (inside a function, or under ``if TYPE_CHECKING:``, which a type checker
    follows). For ``from X import name`` the module ``X.name`` is recorded if it is a module of
    this package."""
    tree = ast.parse(path.read_text(), str(path))
    found: list[tuple[str, bool]] = []

    def visit(node: ast.AST, lazy: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inner = lazy or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef))
            if isinstance(child, ast.If) and 'TYPE_CHECKING' in ast.unparse(child.test):
                for statement in child.body:            # typing only: seen, as lazy
                    visit(ast.Module(body=[statement], type_ignores=[]), True)
                for statement in child.orelse:          # run at import time
                    visit(ast.Module(body=[statement], type_ignores=[]), lazy)
                continue
            if isinstance(child, ast.Import):
                found.extend((alias.name, lazy) for alias in child.names)
            elif isinstance(child, ast.ImportFrom) and child.level == 0 and child.module:
                for alias in child.names:
                    candidate = f'{child.module}.{alias.name}'
                    is_module = any((PACKAGE_DIR.parent / candidate.replace('.', '/')).with_suffix(s).exists()
                                    for s in ('.py',)) or (PACKAGE_DIR.parent / candidate.replace('.', '/')).is_dir()
                    found.append((candidate if is_module else child.module, lazy))
            elif isinstance(child, ast.ImportFrom) and child.level:
                found.append((f'<relative import in {path.name}>', lazy))
            visit(child, inner)

    visit(tree, False)
    return found


#: The message modules rosidl generates (``fall_predictor.msg``, not in git) are not the package's code.
GENERATED = PACKAGE_DIR / 'msg'
MODULES = {module_name(p): p for p in sorted(PACKAGE_DIR.rglob('*.py')) if GENERATED not in p.parents}
GRAPH = {name: imports(path) for name, path in MODULES.items()}


def test_every_sub_package_is_documented_with_what_it_may_import():
    for package in ALLOWED:
        init = PACKAGE_DIR / package / '__init__.py'
        doc = ast.get_docstring(ast.parse(init.read_text()))
        assert doc and 'May import' in doc, f'{init}: docstring must say what the package may import'


def test_no_relative_imports():
    relative = [(m, i) for m, found in GRAPH.items() for i, _ in found if i.startswith('<relative')]
    assert not relative


def layout_violations(module: str, graph: dict[str, list[tuple[str, bool]]]) -> list[str]:
    """The imports of ``module`` its sub-package may not make (ALLOWED), each named."""
    own = sub_package(module)
    eager, lazy_only = ALLOWED[own]
    bad = []
    for target, lazy in graph[module]:
        if not target.startswith(ROOT + '.'):
            continue
        other = sub_package(target)
        if other in ('', own) or other in eager or (lazy and other in lazy_only):
            continue
        where = 'inside a function or TYPE_CHECKING' if lazy else 'module level'
        bad.append(f'{module} imports {target} ({where})')
    return bad


def test_imports_follow_the_layout():
    bad = [v for m in sorted(MODULES) if sub_package(m) for v in layout_violations(m, GRAPH)]
    assert not bad, 'imports the layout forbids:\n' + '\n'.join(bad)


def test_only_the_ros_package_imports_ros():
    bad = [f'{m} imports {t}' for m in sorted(MODULES) if sub_package(m) != 'ros'
           for t, _ in GRAPH[m] if is_ros_module(t.split('.')[0])]
    assert not bad, 'ROS imports outside ros/:\n' + '\n'.join(bad)


def test_the_monitor_uses_numpy_and_pinocchio_only():
    stdlib = sys.stdlib_module_names
    bad = []
    for module in sorted(m for m in MODULES if sub_package(m) == 'monitor'):
        third_party = {t.split('.')[0] for t, _ in GRAPH[module]
                       if t.split('.')[0] not in stdlib and t.split('.')[0] != ROOT and t != '__future__'}
        bad += [f'{module} imports {t}' for t in sorted(third_party - MONITOR_THIRD_PARTY)]
    assert not bad, 'third-party imports in the onboard monitor:\n' + '\n'.join(bad)


def import_edges(graph: dict[str, list[tuple[str, bool]]], modules: set[str]) -> dict[str, set[str]]:
    """Module -> the package modules it imports, at module level, inside functions or for typing.
    Importing ``a.b.c`` also runs ``a/__init__`` and ``a/b/__init__``: an edge to a module is also
    an edge to each package above it."""
    edges: dict[str, set[str]] = {}
    for module, found in graph.items():
        targets = set()
        for target, _ in found:
            parts = target.split('.')
            targets.update(p for p in ('.'.join(parts[:n]) for n in range(1, len(parts) + 1))
                           if p in modules)
        edges[module] = targets - {module}
    return edges


def find_cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Import cycles, each as [a, b, ..., a]; empty iff the graph has none (every cycle has a
    back edge in a depth-first search)."""
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def walk(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(edges.get(node, ())):
            if state.get(nxt) == 1:
                cycles.append(path[path.index(nxt):] + [nxt])
            elif nxt not in state:
                walk(nxt, path + [nxt])
        state[node] = 2

    for module in sorted(edges):
        if module not in state:
            walk(module, [module])
    return cycles


def test_no_import_cycles():
    cycles = find_cycles(import_edges(GRAPH, set(MODULES)))
    assert not cycles, 'import cycles: ' + '; '.join(' -> '.join(c) for c in cycles)


def test_the_checker_sees_cycles_through_function_and_type_checking_imports(tmp_path):
    """A cycle closed only by a function-level import, or only by one under TYPE_CHECKING, is
    found and named; the same modules without the closing import are not a cycle."""
    a, b, c = tmp_path / 'a.py', tmp_path / 'b.py', tmp_path / 'c.py'
    a.write_text('from fall_predictor.fake_b import g\n')
    b.write_text('def g():\n    from fall_predictor.fake_c import h\n')
    c.write_text('from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n'
                 '    from fall_predictor.fake_a import A\nelse:\n    import numpy\n')
    names = {'fall_predictor.fake_a': a, 'fall_predictor.fake_b': b, 'fall_predictor.fake_c': c}
    graph = {name: imports(path) for name, path in names.items()}
    assert ('fall_predictor.fake_a', True) in graph['fall_predictor.fake_c']
    assert ('numpy', False) in graph['fall_predictor.fake_c']
    assert find_cycles(import_edges(graph, set(names))) == [
        ['fall_predictor.fake_a', 'fall_predictor.fake_b', 'fall_predictor.fake_c',
         'fall_predictor.fake_a']]
    c.write_text('import numpy\n')
    graph['fall_predictor.fake_c'] = imports(c)
    assert find_cycles(import_edges(graph, set(names))) == []


def test_the_checker_sees_a_forbidden_import(tmp_path):
    """The checks above can fail: a monitor module importing the simulator is caught and named."""
    bad = tmp_path / 'bad.py'
    bad.write_text('import numpy\n\ndef f():\n    from fall_predictor.sim.pybullet_world import PybulletWorld\n')
    found = imports(bad)
    assert ('fall_predictor.sim.pybullet_world', True) in found
    assert ('numpy', False) in found
    assert layout_violations('fall_predictor.monitor.bad', {'fall_predictor.monitor.bad': found}) == [
        'fall_predictor.monitor.bad imports fall_predictor.sim.pybullet_world '
        '(inside a function or TYPE_CHECKING)']


def test_no_module_over_500_lines():
    long = [f'{m}: {n} lines' for m, n in ((m, MODULES[m].read_text().count('\n')) for m in sorted(MODULES))
            if n > 500]
    assert not long, 'modules over 500 lines (split them by responsibility):\n' + '\n'.join(long)


def test_no_test_benchmark_or_script_over_500_lines():
    """The same rule for the tests, benchmarks and scripts (the tests mirror the modules)."""
    repo = PACKAGE_DIR.parent
    files = [f for d in ('test', 'benchmarks', 'scripts') for f in sorted((repo / d).glob('*.py'))]
    assert len(files) > 100
    long = [f'{f.relative_to(repo)}: {n} lines' for f in files
            if (n := f.read_text().count('\n')) > 500]
    assert not long, 'files over 500 lines (split them by responsibility):\n' + '\n'.join(long)
