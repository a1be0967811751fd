"""The climber planner is a managed (lifecycle) node: it configures, refuses to activate until
every input has arrived, commands nothing unless active, and deactivates/cleans up on request.
Run in one process on the climber graph of launch/climber.launch.xml, lock-step."""
import pytest
from rclpy.lifecycle import TransitionCallbackReturn

from paramotion.errors import UserError
from paramotion.graph import Graph
from paramotion.launch import graph_from_launch

SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE


def _graph(graph, planner_params):
    nodes, _ = graph_from_launch(graph, 'climber', extra_params={
        'climber_planner': planner_params})
    commands = []
    node = nodes['climber_sim']
    from std_msgs.msg import Bool
    from trajectory_msgs.msg import JointTrajectory

    from paramotion.qos import STATE_QOS
    node.create_subscription(JointTrajectory, '/climber/leg_command',
                             lambda m: commands.append(('legs', node.sim_time)), STATE_QOS)
    for r in (1, 2):
        node.create_subscription(Bool, f'/climber/ring{r}/clamp_command',
                                 lambda m: commands.append(('clamp', node.sim_time)), STATE_QOS)
    return nodes['climber_sim'], nodes['climber_planner'], commands


@pytest.mark.slow            # climbs for seconds of sim time through the lifecycle
def test_managed_planner_activates_only_with_its_inputs_and_stops_when_deactivated():
    with Graph() as graph:
        sim, planner, commands = _graph(graph, {'autostart': False})
        assert planner.lifecycle_state == 'unconfigured' and planner.gait is None
        assert planner.trigger_configure() == SUCCESS
        assert planner.lifecycle_state == 'inactive' and planner.gait is not None
        # Nothing has been published yet (time has not started): activation is refused.
        assert planner.trigger_activate() == FAILURE
        assert planner.lifecycle_state == 'inactive'
        assert 'waiting for /climber/joint_states' in planner.last_status.message
        graph.run_lockstep(sim, max_sim_time=1.0)
        assert planner.missing_inputs() == []
        assert commands == []          # inactive: inputs collected, nothing commanded
        assert planner.trigger_activate() == SUCCESS
        assert planner.lifecycle_state == 'active'
        graph.run_lockstep(sim, until=lambda: len(commands) >= 2, max_sim_time=20.0)
        assert len(commands) >= 2 and commands[0][1] >= 1.0, commands[:3]
        assert planner.trigger_deactivate() == SUCCESS
        n, t = len(commands), sim.sim_time
        graph.run_lockstep(sim, max_sim_time=t + 2.0)
        assert len(commands) == n     # deactivated: no command goes out
        assert planner.trigger_cleanup() == SUCCESS
        assert planner.lifecycle_state == 'unconfigured' and planner.gait is None


def test_autostarted_planner_waits_for_every_input_then_climbs():
    """With autostart (the launch file's default) the node configures itself and activates on
    the first planning tick at which every input has arrived."""
    with Graph() as graph:
        sim, planner, commands = _graph(graph, {})
        assert planner.lifecycle_state == 'inactive'
        assert set(planner.missing_inputs()) == {
            '/climber/joint_states', '/climber/ring1/clamp_closed',
            '/climber/ring2/clamp_closed', '/climber/ring1/ultrasonic',
            '/climber/ring2/ultrasonic'}
        graph.run_lockstep(sim, until=lambda: len(commands) >= 2, max_sim_time=20.0)
        assert planner.lifecycle_state == 'active'
        assert len(commands) >= 2


def test_bad_robot_file_fails_configure_with_one_line(tmp_path):
    with Graph() as graph:
        from climber_pkg.planner_node import ClimberPlannerNode
        with pytest.raises(UserError) as err:
            graph.add(ClimberPlannerNode, robot_config=str(tmp_path / 'missing.yaml'))
        assert 'missing.yaml' in str(err.value) and '\n' not in str(err.value)
        node = graph.add(ClimberPlannerNode, autostart=False,
                         robot_config=str(tmp_path / 'missing.yaml'))
        assert node.trigger_configure() == FAILURE
        assert node.lifecycle_state == 'unconfigured'
