"""smoke_sim: PyBullet cart on a rail facing a wall (hardware stand-in, owns /clock).

Subscribes ``/smoke/cmd_vel`` (geometry_msgs/Twist, linear.x used) and drives the rail joint
with a velocity motor of limited force; publishes the cart's true pose on
``/smoke/ground_truth`` (geometry_msgs/PoseStamped, frame ``map``) every publish period.
"""
from typing import Any

from geometry_msgs.msg import PoseStamped, Twist

from paramotion.messages import pose_stamped
from paramotion.node import Param, run_node
from paramotion.qos import SENSOR_QOS, STATE_QOS
from paramotion.sim import SimulationNode


class SmokeSimNode(SimulationNode):
    """One prismatic cart and one wall in PyBullet."""

    PARAMS = SimulationNode.PARAMS + (
        Param('start_x', 0.0, 'Initial cart centre x in map frame (m).', min=-100.0, max=100.0,
              read_only=True),
        Param('wall_x', 5.0, 'x of the wall face the cart drives toward (m).', min=-100.0,
              max=100.0, read_only=True),
        Param('cart_half_length', 0.2, 'Half length of the cart along x (m).', min=0.01,
              max=5.0, read_only=True),
        Param('max_force', 50.0, 'Force limit of the rail motor (N).', min=0.0, max=1e4),
    )

    def __init__(self, node_name: str = 'smoke_sim', **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        p, b = self.params, self.bullet
        b.createMultiBody(0.0, b.createCollisionShape(b.GEOM_PLANE))
        wall_shape = b.createCollisionShape(b.GEOM_BOX, halfExtents=[0.05, 1.0, 0.5])
        b.createMultiBody(0.0, wall_shape, basePosition=[p.wall_x + 0.05, 0.0, 0.5])
        cart_shape = b.createCollisionShape(b.GEOM_BOX, halfExtents=[p.cart_half_length, 0.15,
                                                                     0.1])
        rail_shape = b.createCollisionShape(b.GEOM_SPHERE, radius=0.01)
        self.cart = b.createMultiBody(
            baseMass=0.0, baseCollisionShapeIndex=rail_shape, basePosition=[0.0, 0.0, 0.2],
            linkMasses=[2.0], linkCollisionShapeIndices=[cart_shape],
            linkVisualShapeIndices=[-1], linkPositions=[[0.0, 0.0, 0.0]],
            linkOrientations=[[0, 0, 0, 1]], linkInertialFramePositions=[[0, 0, 0]],
            linkInertialFrameOrientations=[[0, 0, 0, 1]], linkParentIndices=[0],
            linkJointTypes=[b.JOINT_PRISMATIC], linkJointAxis=[[1.0, 0.0, 0.0]])
        b.resetJointState(self.cart, 0, p.start_x)
        self.command = 0.0
        self.create_subscription(Twist, '/smoke/cmd_vel', self._on_cmd, STATE_QOS)
        self.truth_pub = self.create_publisher(PoseStamped, '/smoke/ground_truth', SENSOR_QOS)

    def _on_cmd(self, msg):
        self.command = float(msg.linear.x)

    @property
    def cart_x(self) -> float:
        """True cart centre x (m)."""
        return self.bullet.getJointState(self.cart, 0)[0]

    def step_physics(self, dt: float) -> None:
        """Drive the rail motor at the commanded speed for one physics step."""
        self.bullet.setJointMotorControl2(self.cart, 0, self.bullet.VELOCITY_CONTROL,
                                          targetVelocity=self.command,
                                          force=self.params.max_force)
        self.bullet.stepSimulation()

    def publish_state(self) -> None:
        """Publish the cart's true pose."""
        self.truth_pub.publish(pose_stamped(self.stamp(), 'map', (self.cart_x, 0.0, 0.2)))


def main(args: list[str] | None = None) -> None:
    """Console script ``smoke_sim``."""
    run_node(SmokeSimNode, args)


if __name__ == '__main__':
    main()
