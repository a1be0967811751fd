"""The ROS 2 XML launch interpreter (paramotion.launch_xml) and the packaged launch files."""
import pytest

from paramotion import launch_xml as lx
from paramotion.launch_xml import LaunchError

GRAPHS = ['coverage', 'climber', 'fast', 'workspace', 'voronoi']


def write(tmp_path, body, name='t.launch.xml'):
    path = tmp_path / name
    path.write_text(body)
    return path


def load(tmp_path, body, **args):
    return lx.load(write(tmp_path, f'<launch>\n{body}\n</launch>\n'), args)


def one_line_error(tmp_path, body, **args):
    with pytest.raises(LaunchError) as info:
        load(tmp_path, body, **args)
    text = str(info.value)
    assert '\n' not in text
    return text


def test_args_defaults_overrides_and_typed_params(tmp_path):
    body = """
  <arg name="rate" default="10.0" description="Hz"/>
  <arg name="name" default="alpha"/>
  <node pkg="paramotion" exec="smoke_controller" name="$(var name)_ctl" namespace="ns">
    <param name="f" value="$(var rate)"/>
    <param name="i" value="3"/>
    <param name="b" value="true"/>
    <param name="s" value="a path/x.json"/>
    <param name="small" value="1e-05"/>
    <param name="l" value="[/a:2, /b:1]"/>
    <param name="nums" value="1,2.5" value-sep=","/>
    <param name="empty" value=""/>
    <remap from="cmd_vel" to="/robot/cmd_vel"/>
    <env name="FOO" value="bar"/>
  </node>"""
    d = load(tmp_path, body)
    n = d.nodes[0]
    assert (n.package, n.executable, n.name, n.namespace) == ('paramotion', 'smoke_controller',
                                                              'alpha_ctl', 'ns')
    assert n.params == {'f': 10.0, 'i': 3, 'b': True, 's': 'a path/x.json', 'small': 1e-05,
                        'l': ['/a:2', '/b:1'], 'nums': [1.0, 2.5], 'empty': ''}
    assert type(n.params['i']) is int and type(n.params['f']) is float
    assert n.remaps == [('cmd_vel', '/robot/cmd_vel')]
    assert n.env == {'FOO': 'bar'}
    d = load(tmp_path, body, rate=2, name='beta')
    assert d.nodes[0].params['f'] == 2 and d.nodes[0].name == 'beta_ctl'
    assert d.values['rate'] == '2' and d.args['rate'].description == 'Hz'


def test_conditions_let_group_and_substitutions(tmp_path, monkeypatch):
    monkeypatch.setenv('PARAMOTION_TEST_ENV', 'from-env')
    monkeypatch.delenv('PARAMOTION_TEST_UNSET', raising=False)
    body = """
  <arg name="record" default="false"/>
  <arg name="mode" default="climb"/>
  <arg name="delta" default="0.1"/>
  <let name="n" value="3" unless="$(var record)"/>
  <let name="n" value="5" if="$(var record)"/>
  <node pkg="paramotion" exec="a" name="a">
    <param name="n" value="$(var n)"/>
    <param name="turn" value="$(equals $(var mode) turn)"/>
    <param name="dmin" value="$(eval 'min(0.05, $(var delta))')"/>
    <param name="len" value="$(eval &quot;0.7 if '$(var mode)' == 'turn' else 0.5&quot;)"/>
    <param name="env" value="$(env PARAMOTION_TEST_ENV)"/>
    <param name="opt" value="x$(optenv PARAMOTION_TEST_UNSET)y"/>
    <param name="dflt" value="$(env PARAMOTION_TEST_UNSET fallback)"/>
    <param name="file" value="$(filename)"/>
    <param name="dir" value="$(dirname)"/>
  </node>
  <node pkg="paramotion" exec="rec" name="rec" if="$(var record)"/>
  <group if="$(not-equals $(var mode) climb)">
    <let name="inner" value="1"/>
    <node pkg="paramotion" exec="g" name="g"/>
  </group>"""
    d = load(tmp_path, body)
    a = d.node('a')
    assert a.params == {'n': 3, 'turn': False, 'dmin': 0.05, 'len': 0.5, 'env': 'from-env',
                        'opt': 'xy', 'dflt': 'fallback', 'file': 't.launch.xml',
                        'dir': str(tmp_path.resolve())}
    assert [n.label for n in d.nodes] == ['a']
    d = load(tmp_path, body, record=True, mode='turn', delta=0.03)
    a = d.node('a')
    assert (a.params['n'], a.params['turn'], a.params['dmin'], a.params['len']) == \
        (5, True, 0.03, 0.7)
    assert [n.label for n in d.nodes] == ['a', 'rec', 'g']
    assert 'inner' not in d.values               # a group is scoped by default


def test_choices_and_required_args(tmp_path):
    body = """
  <arg name="detector" default="extended"><choice value="extended"/><choice value="robot"/></arg>
  <arg name="world"/>"""
    assert load(tmp_path, body, world='w.json').values['detector'] == 'extended'
    text = one_line_error(tmp_path, body, world='w', detector='laser')
    assert "launch argument 'detector' = 'laser' not allowed; choices: extended, robot" in text
    assert "launch argument 'world' is required (pass world:=VALUE)" in \
        one_line_error(tmp_path, body)


@pytest.mark.parametrize('body, expected', [
    ('<node pkg="paramotion" exec="a"', 'not well-formed XML'),
    ('<nodes pkg="paramotion" exec="a"/>', 't.launch.xml:2: unknown tag <nodes>'),
    ('<node pkg="paramotion" exec="a" nmae="x"/>',
     "t.launch.xml:2: <node> has unknown attribute 'nmae'"),
    ('<node pkg="paramotion" exec="a"><parm name="x" value="1"/></node>',
     'unknown tag <parm> in <node>'),
    ('<node pkg="paramotion" exec="a"><param name="x"/></node>',
     "<param> needs attribute 'value'"),
    ('<node pkg="paramotion" name="a"/>', "<node> needs attribute 'exec'"),
    ('<node pkg="paramotion" exec="$(var nope)"/>', '$(var nope): no such launch argument'),
    ('<node pkg="paramotion" exec="$(find-exec x)"/>', 'unknown substitution $(find-exec'),
    ('<node pkg="paramotion" exec="$(var x"/>', 'unclosed substitution'),
    ('<node pkg="paramotion" exec="a" if="maybe"/>', "if: 'maybe' is not a boolean"),
    ('<node pkg="paramotion" exec="a" respawn_delay="-1"/>', 'respawn_delay'),
    ('<node pkg="paramotion" exec="$(eval \'__import__(1)\')"/>', '$(eval'),
    ('<node pkg="paramotion" exec="$(env PARAMOTION_SURELY_UNSET_VAR)"/>',
     'environment variable not set'),
])
def test_bad_launch_files_fail_with_one_line(tmp_path, body, expected):
    assert expected in one_line_error(tmp_path, body)


def test_unknown_launch_argument_and_bad_cli_syntax(tmp_path):
    assert "unknown launch argument 'foo'" in one_line_error(
        tmp_path, '<arg name="a" default="1"/>', foo=1)
    assert lx.parse_cli_args(['a:=1', 'b:=x:=y']) == {'a': '1', 'b': 'x:=y'}
    with pytest.raises(LaunchError, match='expected name:=value'):
        lx.parse_cli_args(['a=1'])


def test_root_must_be_launch(tmp_path):
    with pytest.raises(LaunchError, match='root element is <robot>, expected <launch>'):
        lx.load(write(tmp_path, '<robot/>'))


def test_safe_eval_refuses_what_is_not_an_expression_of_values():
    assert lx.safe_eval('2 * pi > 6 and not False') is True
    assert lx.safe_eval("'a' if 1 < 2 <= 2 else 'b'") == 'a'
    assert lx.safe_eval('math.sqrt(16) + abs(-1)') == 5.0
    for bad in ('__import__("os")', 'open("x")', '(1).__class__', '[x for x in y]'):
        with pytest.raises(Exception):
            lx.safe_eval(bad)


@pytest.mark.parametrize('name', GRAPHS)
def test_packaged_launch_files_resolve_and_their_nodes_exist(name):
    """Every node of every shipped launch file has an installed executable and declares every
    parameter the file sets, with and without the recorder."""
    from paramotion.launch import Launcher
    for record in (False, True):
        desc = lx.load(name, {'record': record})
        assert desc.path.name == f'{name}.launch.xml'
        launcher = Launcher(desc).prepare()       # raises on a missing exec / unknown param
        assert len(launcher.procs) == len(desc.nodes) >= 1
        assert any(n.executable == 'bag_recorder' for n in desc.nodes) == record


def test_default_inputs_are_shipped_with_the_package():
    from pathlib import Path
    cov = lx.load('coverage').node('coverage_sim').params['world']
    climb = lx.load('climber').node('climber_sim').params['trunk_file']
    for path in (cov, climb):
        assert Path(path).is_file(), path


def test_scenario_runner_builds_the_graph_from_the_launch_file():
    """The one-process runner composes exactly the launch file's nodes and parameters."""
    from paramotion.graph import Graph
    from paramotion.launch import graph_from_launch
    with Graph() as graph:
        nodes, topics = graph_from_launch(graph, 'coverage', {'detector': 'robot',
                                                              'planner': 'grid',
                                                              'radius': 0.3})
        assert sorted(nodes) == ['coverage_monitor', 'coverage_planner', 'coverage_sim',
                                 'coverage_sonar']
        monitor = nodes['coverage_monitor']
        assert monitor.params.delta == 0.3 and monitor.params.radius == 0.3
        assert nodes['coverage_sim'].params.lockstep is True
        assert nodes['coverage_planner'].params.detector == 'robot'
        assert nodes['coverage_planner'].params.planner == 'grid'
        assert '/coverage/covered_fraction' in topics


def test_node_refuses_an_undeclared_parameter_in_one_process():
    from paramotion.errors import ParameterError
    from paramotion.graph import Graph
    from paramotion.smoke.controller_node import SmokeControllerNode
    with Graph() as graph, pytest.raises(ParameterError) as info:
        graph.add(SmokeControllerNode, name='ctl', tagret=1.0)
    assert str(info.value) == ("ctl: unknown parameter 'tagret' (declared: target, gain, "
                               'max_speed, timeout)')


def test_interpreter_imports_no_rclpy():
    """launch_xml is an algorithm-style module: reading launch files needs no ROS."""
    import subprocess
    import sys
    code = ('import sys\nfrom paramotion import launch_xml\nlaunch_xml.load("coverage")\n'
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'rclpy'))")
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=60, cwd=lx._REPO)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip() == '[]'
