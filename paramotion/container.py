"""A component container: several nodes in one process, spun by one executor.

A ROS 2 user puts the nodes that talk to each other at a high rate into one component
container, so that their messages never leave the process and one executor serves them all.
:class:`ComponentContainer` is that container for paramotion's Python nodes: a node of its own
whose ``components`` parameter names the nodes it starts (its subclass lists which node classes
it can hold, by node name), each with

- **its own name**, as a separate process would have (``ros2 node list`` shows every one);
- **its own parameters**: the container declares ``<node>.<parameter>`` for every parameter of
  every component, with the component's descriptor, and hands the values given (launch-file
  ``<param name="fast_tracker.latency" .../>``, ``-p fast_tracker.latency:=0.03``) to that
  node as its start-up overrides; the node validates them as it would in its own process and
  refuses a bad one with its own one-line reason. At run time each node has its own parameter
  services (``ros2 param set /fast_tracker latency 0.03``);
- **the process's remappings**: topic remappings given to the container (``<remap>``, ``-r
  from:=to``, node-targeted ``fast_tracker:from:=to``) apply to its components, and its
  namespace is theirs; the node-name rule ``__node:=`` names the container only.

:func:`paramotion.node.run_node` runs a container like any node: ``spin_node`` adds the
components to the same executor (``PARAMOTION_EXECUTOR``), and the container destroys them
when it is destroyed.
"""
from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from paramotion.node import Param, ParamotionNode, overrides_from_dict

_NAME_RULES = ('__node', '__name', '__ns')


def component_params(components: dict[str, type[ParamotionNode]]) -> tuple[Param, ...]:
    """The container's parameters for ``components`` ({node name: node class}): which to start,
    and ``<node>.<parameter>`` for each component parameter (read only: the start-up value)."""
    names = tuple(components)
    out = [Param('components', list(names), 'Nodes this container starts, by node name (a '
                 'subset of the default list).', choices=names, read_only=True)]
    for name, cls in components.items():
        for spec in cls.PARAMS:
            out.append(Param(f'{name}.{spec.name}', spec.default,
                             f"Start-up value of {name}'s '{spec.name}' (set it on /{name} "
                             f'at run time): {spec.description}', min=spec.min, max=spec.max,
                             choices=spec.choices, read_only=True))
    return tuple(out)


def remap_rules(argv: Sequence[str]) -> list[str]:
    """The topic and service remapping rules of the ``--ros-args`` sections of ``argv``
    (``-r``/``--remap``), without the node-name and namespace rules, which name the process's
    own node."""
    rules, ros, i = [], False, 0
    argv = list(argv)
    while i < len(argv):
        arg = argv[i]
        if arg == '--ros-args':
            ros = True
        elif arg == '--':
            ros = False
        elif ros and arg in ('-r', '--remap') and i + 1 < len(argv):
            rule = argv[i + 1]
            i += 1
            lhs = rule.partition(':=')[0].rpartition(':')[2]
            if lhs not in _NAME_RULES:
                rules.append(rule)
        i += 1
    return rules


class ComponentContainer(ParamotionNode):
    """A node that starts its ``COMPONENTS`` in its own context, to be spun with them.

    Subclasses set ``COMPONENTS = {node name: node class}`` (in start order) and
    ``PARAMS = component_params(COMPONENTS)``. ``self.components`` holds the started nodes.
    """

    COMPONENTS: dict[str, type[ParamotionNode]] = {}

    def __init__(self, node_name: str, **kwargs: Any) -> None:
        own_args = list(kwargs.get('cli_args') or [])
        global_args = kwargs.get('use_global_arguments', True)
        super().__init__(node_name, **kwargs)
        given = set(self._parameter_overrides)
        rules = (remap_rules(sys.argv) if global_args else []) + remap_rules(own_args)
        cli = ['--ros-args'] + [x for rule in rules for x in ('-r', rule)] if rules else None
        namespace = self.get_namespace()
        sim_time = self.get_parameter('use_sim_time').value
        services = {k: kwargs[k] for k in ('start_parameter_services',) if k in kwargs}
        type_service = self.get_parameter('start_type_description_service').value
        self.components = []
        try:
            for name, cls in self.COMPONENTS.items():
                if name not in self.params.components:
                    continue
                prefix = name + '.'
                params = {key[len(prefix):]: self.get_parameter(key).value
                          for key in given if key.startswith(prefix)}
                params.setdefault('use_sim_time', sim_time)
                params.setdefault('start_type_description_service', type_service)
                self.components.append(cls(
                    node_name=name, context=self.context, namespace=namespace,
                    cli_args=cli, use_global_arguments=False,
                    parameter_overrides=overrides_from_dict(params), **services))
        except Exception:
            self.destroy_node()
            raise

    def destroy_node(self) -> None:
        """Destroy the components (last started first), then the container."""
        while self.components:
            self.components.pop().destroy_node()
        return super().destroy_node()


__all__ = ['ComponentContainer', 'component_params', 'remap_rules']
