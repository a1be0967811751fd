"""Architecture rule: the algorithm modules (each paper's math) import no rclpy."""
import ast
import functools
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

ALGORITHMS = [
    'paramotion.gough_stewart', 'paramotion.range_sensing', 'paramotion.smoke.control',
    'voronoi_pkg.predicates', 'voronoi_pkg.distance', 'voronoi_pkg.planar',
    'voronoi_pkg.diagram', 'voronoi_pkg.planner', 'voronoi_pkg.spatial321',
    'voronoi_pkg.spatial321_roadmap', 'voronoi_pkg.ties', 'voronoi_pkg.measures',
    'voronoi_pkg.grid_baseline',
    'coverage_pkg.world', 'coverage_pkg.sonar', 'coverage_pkg.mapping', 'coverage_pkg.gvd',
    'coverage_pkg.morse', 'coverage_pkg.hierarchical_graph', 'coverage_pkg.planner',
    'coverage_pkg.cvs', 'coverage_pkg.baseline', 'coverage_pkg.algorithm1',
    'coverage_pkg.paper.graph_nodes', 'coverage_pkg.paper.sense_events',
    'coverage_pkg.paper.node_creation', 'coverage_pkg.paper.morse_coverage',
    'coverage_pkg.paper.trace_gvd', 'coverage_pkg.paper.find_uncovered',
    'climber_pkg.trunk', 'climber_pkg.correction', 'climber_pkg.prediction', 'climber_pkg.gait',
    'cable_robot_pkg.fast.configuration', 'cable_robot_pkg.fast.cables',
    'cable_robot_pkg.fast.wind',
    'cable_robot_pkg.fast.focal_surface', 'cable_robot_pkg.fast.pid',
    'cable_robot_pkg.fast.isolation', 'cable_robot_pkg.fast.plant',
    'cable_robot_pkg.cdrpm.description', 'cable_robot_pkg.cdrpm.kinematics',
    'cable_robot_pkg.cdrpm.collisions', 'cable_robot_pkg.cdrpm.workspace',
    'cable_robot_pkg.cdrpm.wrench_closure', 'cable_robot_pkg.cdrpm.paper_figures',
]


@pytest.mark.slow            # a fresh interpreter imports every algorithm module
def test_algorithm_modules_do_not_import_rclpy():
    code = ('import sys, importlib\n'
            f'for m in {ALGORITHMS!r}:\n'
            '    importlib.import_module(m)\n'
            "bad = sorted(m for m in sys.modules if m == 'rclpy' or m.startswith('rclpy.'))\n"
            'print(bad)\n')
    proc = subprocess.run([sys.executable, '-c', code], cwd=REPO, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip().splitlines()[-1] == '[]'


# Modules allowed to use rclpy: the nodes (``*_node``), and the ROS plumbing, scenario runners
# and command-line front ends that build or drive graphs. Everything else in the four packages
# is an algorithm module (or plain tooling) and must not mention rclpy at all.
ROS_SIDE = ('_node', '.scenario', '.cli', '.bench', '.sweep', '.demo', '.launch', '.launch_xml',
            '.graph', '.executors', '.node', '.qos', '.clock', '.clock_watchdog', '.sim',
            '.msgtypes', '.container', '.intra_process', '.ros_messages', '.qos_yaml', '.reader',
            '.shutdown')


@functools.cache
def _tree(path):
    """The parsed source of ``path`` (several checks walk the same files)."""
    return ast.parse(path.read_text(), str(path))


def _imports_rclpy(path):
    for node in ast.walk(_tree(path)):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [node.module or '']
        else:
            continue
        if any(n == 'rclpy' or n.startswith('rclpy.') for n in names):
            return True
    return False


def test_no_module_outside_the_ros_side_imports_rclpy_even_lazily():
    """Found by walking the source, so a new algorithm module is covered without being listed:
    not even a function-level ``import rclpy`` outside nodes, plumbing and front ends."""
    checked, offenders = 0, []
    for pkg in ('paramotion',) + ROBOT_PACKAGES:
        for path in sorted((REPO / pkg).rglob('*.py')):
            rel = path.relative_to(REPO).with_suffix('')
            module = '.'.join(rel.parts)
            if module.endswith('.__init__'):
                module = module[:-len('.__init__')]
            if '.cli.' in module + '.' or module.endswith(ROS_SIDE):
                continue
            checked += 1
            if _imports_rclpy(path):
                offenders.append(module)
    assert checked >= 60
    assert offenders == []
    assert set(ALGORITHMS) <= {m for m in ALGORITHMS if not m.endswith(ROS_SIDE)}


ROBOT_PACKAGES = ('coverage_pkg', 'climber_pkg', 'cable_robot_pkg', 'voronoi_pkg')


def _imported_modules(path):
    for node in ast.walk(_tree(path)):
        if isinstance(node, ast.Import):
            yield from (a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            yield node.module or ''


def test_the_shared_package_imports_no_robot_package():
    """Issue 33: ``paramotion/`` holds only what every robot shares; the command line and the
    report reach the robot packages by module name (importlib), never by an import."""
    offenders = []
    for path in sorted((REPO / 'paramotion').rglob('*.py')):
        for name in _imported_modules(path):
            if name.split('.')[0] in ROBOT_PACKAGES:
                offenders.append(f'{path.relative_to(REPO)}: {name}')
    assert offenders == []


def test_every_paper_has_a_report_generator_wired_into_paramotion_report():
    """Each part's measured results come from its own write_report, dispatched by name."""
    import importlib

    from paramotion.report import REPORTS
    for part, module in REPORTS.items():
        assert callable(getattr(importlib.import_module(module), 'write_report', None)), part
    for pkg in ('coverage_pkg', 'climber_pkg', 'cable_robot_pkg.fast', 'cable_robot_pkg.cdrpm',
                'voronoi_pkg'):
        assert f'{pkg}.report' in REPORTS.values(), pkg


def test_each_robot_has_one_room():
    """Issue 14: cable_robot_pkg holds one folder per robot and nothing else at its top level;
    each robot folder keeps its nodes, scenario/CLI and config beside its algorithms."""
    top = REPO / 'cable_robot_pkg'
    assert sorted(p.name for p in top.glob('*.py')) == ['__init__.py']
    for robot, cli in (('fast', 'scenario.py'), ('cdrpm', 'cli')):
        room = top / robot
        assert (room / cli).exists(), f'{robot}: {cli} missing'
        assert any(room.glob('*_node.py')), f'{robot}: no node beside the algorithms'
        assert any((room / 'config').glob('*.yaml')), f'{robot}: no config/'
    assert (REPO / 'voronoi_pkg' / 'cli.py').exists()
    assert not (REPO / 'paramotion' / 'voronoi').exists()


def test_every_console_script_resolves():
    """Each node executable (``paramotion.start.NODES``, registered by setup.py as
    ``paramotion.start:<name>``) names an importable module with main() and an entry point."""
    import importlib

    import paramotion.start as start
    assert len(start.NODES) >= 15
    assert "f'{name} = paramotion.start:{name}' for name in NODES" in \
        (REPO / 'setup.py').read_text()
    for name, module in start.NODES.items():
        assert callable(getattr(importlib.import_module(module), 'main', None)), name
        assert getattr(start, name).__name__ == name
    with pytest.raises(AttributeError, match='no node executable'):
        start.not_a_node  # noqa: B018


# Issue 33: packages whose algorithm modules carry type hints on every public function, method
# and class; the others join the list as their owners finish.
TYPED_PACKAGES = ['climber_pkg', 'cable_robot_pkg/cdrpm', 'cable_robot_pkg/fast', 'voronoi_pkg',
                  'coverage_pkg']


def _typed_algorithm_sources(package):
    """Algorithm modules of ``package``: not a node, not the command line or the scenario
    runner, no rclpy import."""
    for path in sorted((REPO / package).rglob('*.py')):
        folders = path.relative_to(REPO / package).parts[:-1]
        if (path.name.endswith('_node.py') or 'cli' in folders
                or path.name in ('cli.py', 'scenario.py', '__init__.py') or _imports_rclpy(path)):
            continue
        yield path


def _untyped_public_functions(path):
    """``file:line name (what is missing)`` for each public function or method (of a public
    class) with an unannotated argument (self/cls aside) or no return annotation
    (``__init__`` aside)."""
    out = []

    def visit(body, prefix):
        for node in body:
            if isinstance(node, ast.ClassDef) and not node.name.startswith('_'):
                visit(node.body, f'{prefix}{node.name}.')
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                if node.name.startswith('_') and node.name != '__init__':
                    continue
                a = node.args
                args = a.posonlyargs + a.args + a.kwonlyargs + [
                    x for x in (a.vararg, a.kwarg) if x is not None]
                missing = [x.arg for x in args
                           if x.annotation is None and x.arg not in ('self', 'cls')]
                if node.returns is None and node.name != '__init__':
                    missing.append('return')
                if missing:
                    out.append(f'{path.relative_to(REPO)}:{node.lineno} {prefix}{node.name} '
                               f'({", ".join(missing)})')

    visit(_tree(path).body, '')
    return out


def test_public_functions_of_the_shared_layer_are_typed():
    """Issue 33: in ``paramotion/`` every public function and method is annotated, nodes,
    command line, launch and bag tools included (not only algorithm modules)."""
    paths = sorted((REPO / 'paramotion').rglob('*.py'))
    assert len(paths) >= 30
    offenders = [entry for path in paths for entry in _untyped_public_functions(path)]
    assert offenders == [], (f'{len(offenders)} untyped public functions in paramotion/:\n'
                             + '\n'.join(offenders))


@pytest.mark.parametrize('package', TYPED_PACKAGES)
def test_public_functions_of_algorithm_modules_are_typed(package):
    """Issue 33: every public function and method of an algorithm module has annotated
    arguments and a return annotation (found by walking the source, so new modules count)."""
    paths = list(_typed_algorithm_sources(package))
    assert len(paths) >= 3, f'{package}: algorithm modules not found'
    offenders = [entry for path in paths for entry in _untyped_public_functions(path)]
    assert offenders == [], (f'{len(offenders)} untyped public functions in {package}:\n'
                             + '\n'.join(offenders))
