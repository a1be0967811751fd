"""PyBullet simulation node base: the robot hardware stand-in that owns ``/clock``.

Each :class:`SimulationNode` has its own PyBullet physics client (DIRECT, headless), so several
simulations can live in one process. Every publish period it runs
``round(publish_period / physics_dt)`` physics steps of ``physics_dt`` (:meth:`step_physics`),
then publishes ``/clock`` and its state (:meth:`publish_state`).
"""
from __future__ import annotations

import ctypes
import functools
import os
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

from paramotion.clock import NS, ClockSourceNode
from paramotion.node import Param

if TYPE_CHECKING:
    from pybullet_utils.bullet_client import BulletClient


@contextmanager
def quiet_stdout() -> Iterator[None]:
    """Silence C-level stdout (PyBullet prints its build time and argv[0] on start-up), which
    would otherwise mix into scenario summaries and ``ros2 run`` output."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        ctypes.CDLL(None).fflush(None)  # flush C stdio into /dev/null before restoring
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


@functools.cache
def _client_class() -> type[BulletClient]:
    """``BulletClient`` with ``_client = -1`` until ``pybullet.connect`` returns.

    ``BulletClient.__init__`` sets ``_client`` only after connecting, so a Ctrl-C during the
    connection leaves an object without it. Its ``__del__`` would look the name up on the
    ``pybullet`` module, and Python would print the ``AttributeError`` as ignored under the
    node's quiet exit. With the class default, ``__del__`` sees no connection and does
    nothing.
    """
    from pybullet_utils.bullet_client import BulletClient

    class Client(BulletClient):
        _client = -1

    return Client


def bullet_client() -> BulletClient:
    """A new headless (DIRECT) PyBullet client, without the start-up banner."""
    with quiet_stdout():
        import pybullet
        return _client_class()(connection_mode=pybullet.DIRECT)


class SimulationNode(ClockSourceNode):
    """Base class of the PyBullet simulator nodes."""

    PARAMS = ClockSourceNode.PARAMS + (
        Param('physics_dt', 0.001, 'PyBullet time step in seconds.', min=1e-5, max=0.1,
              read_only=True),
        Param('gravity', -9.81, 'Gravity along world z in m/s^2 (REP 103: z up).',
              min=-20.0, max=0.0, read_only=True),
    )

    def __init__(self, node_name: str, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.bullet = bullet_client()
        self.bullet.setGravity(0.0, 0.0, self.params.gravity)
        self.bullet.setTimeStep(self.params.physics_dt)
        self.substeps = max(1, int(round(self.params.publish_period / self.params.physics_dt)))

    def bullet_function(self, name: str, *args: Any) -> Callable[..., Any]:
        """The PyBullet function ``name`` bound to this node's client and to the leading
        ``args``, looked up once. ``self.bullet.<name>`` looks the name up and wraps it in a
        new partial on every access, which a simulator's per-step calls pay each time."""
        import pybullet
        return functools.partial(getattr(pybullet, name), *args,
                                 physicsClientId=self.bullet._client)

    def check_params(self, values: dict[str, Any]) -> str | None:
        """The clock rules, and ``publish_period`` a whole number of physics steps."""
        reason = super().check_params(values)
        if reason:
            return reason
        ratio = values['publish_period'] / values['physics_dt']
        if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
            return (f"parameter 'publish_period' = {values['publish_period']} must be a whole "
                    f"multiple of 'physics_dt' = {values['physics_dt']}")
        return None

    def advance_time(self, period_ns: int) -> None:
        """Run the period as ``substeps`` physics steps of ``physics_dt``."""
        dt = self.params.physics_dt
        for _ in range(self.substeps):
            self.step_physics(dt)

    def step_physics(self, dt: float) -> None:
        """Subclass hook: apply commands/forces, then ``self.bullet.stepSimulation()``."""
        self.bullet.stepSimulation()

    def destroy_node(self) -> None:
        """Disconnect the PyBullet client, then destroy the node."""
        try:
            self.bullet.disconnect()
        except Exception:  # already disconnected (e.g. destroyed twice)
            pass
        return super().destroy_node()


__all__ = ['NS', 'SimulationNode', 'bullet_client', 'quiet_stdout']
