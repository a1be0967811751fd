"""Node plumbing shared by every paramotion node: typed, ranged, validated parameters.

A node lists its parameters once as :class:`Param` specs. :class:`ParamotionNode` declares each
with a ``ParameterDescriptor`` (type, range, description), checks the start-up values (command
line overrides or a Graph's overrides) before the node does anything else, and installs an
on-set callback that refuses a bad change with a one-line reason naming the parameter and the
allowed range. A node never starts half-configured: a bad start-up value raises
:class:`paramotion.errors.ParameterError` from the constructor.

``run_node`` is the standard Jazzy ``main()`` body so that every executable behaves the same on
Ctrl-C, on ``ros2 lifecycle``-less external shutdown and on a bad parameter. It exits 0 without
a traceback however many SIGINT/SIGTERM arrive (a terminal Ctrl-C under ``ros2 launch`` sends
two): see :mod:`paramotion.shutdown`.
"""
from __future__ import annotations

import math
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any, NoReturn, Optional

import rclpy
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
    SetParametersResult,
)
from rclpy._rclpy_pybind11 import RCLError
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions

from paramotion.clock_watchdog import attach as attach_clock_watchdog
from paramotion.errors import ParameterError, UserError
from paramotion.executors import node_executor_kind, spin_node
from paramotion.shutdown import (
    ShutdownSignals,
    ShutdownWaker,
    bounded_middleware_teardown,
    exit_now,
)

_INT_LIMIT = 2 ** 62


@dataclass(frozen=True)
class Param:
    """Specification of one ROS parameter.

    ``default`` fixes the type (bool, int, float, str or a homogeneous list of them).
    ``min``/``max`` bound numbers (inclusive; either may be omitted). ``choices`` restricts a
    string (or number) to a set. ``read_only`` parameters can only be set at start-up.
    """

    name: str
    default: Any
    description: str
    min: Optional[float] = None
    max: Optional[float] = None
    choices: Optional[tuple] = None
    read_only: bool = False

    @property
    def ptype(self) -> Parameter.Type:
        """The rclpy ``Parameter.Type`` matching the default value."""
        return Parameter.Type.from_parameter_value(self.default)

    def allowed(self) -> str:
        """Human-readable allowed set, used in refusal messages."""
        if self.choices is not None:
            return 'one of ' + ', '.join(repr(c) for c in self.choices)
        lo = '-inf' if self.min is None else repr(self.min)
        hi = 'inf' if self.max is None else repr(self.max)
        if self.min is None and self.max is None:
            return f'any {self.ptype.name.lower()}'
        return f'{self.ptype.name.lower()} in [{lo}, {hi}]'

    def descriptor(self) -> ParameterDescriptor:
        """Build the ParameterDescriptor advertised to tools (ros2 param describe)."""
        desc = ParameterDescriptor(
            name=self.name, type=self.ptype.value, description=self.description,
            read_only=self.read_only)
        if self.choices is not None:
            desc.additional_constraints = 'one of: ' + ', '.join(str(c) for c in self.choices)
        elif self.ptype == Parameter.Type.DOUBLE and (
                self.min is not None or self.max is not None):
            # rclpy enforces descriptor ranges itself; +-inf stand for an open end.
            desc.floating_point_range = [FloatingPointRange(
                from_value=-math.inf if self.min is None else float(self.min),
                to_value=math.inf if self.max is None else float(self.max), step=0.0)]
        elif self.ptype == Parameter.Type.INTEGER and (
                self.min is not None or self.max is not None):
            desc.integer_range = [IntegerRange(
                from_value=-_INT_LIMIT if self.min is None else int(self.min),
                to_value=_INT_LIMIT if self.max is None else int(self.max), step=1)]
        return desc

    def check(self, value: Any) -> str | None:
        """Return None if ``value`` is acceptable, else a one-line reason naming the parameter."""
        expected = self.ptype
        if expected == Parameter.Type.DOUBLE and isinstance(value, int) \
                and not isinstance(value, bool):
            value = float(value)
        try:
            actual = Parameter.Type.from_parameter_value(value)
        except TypeError:
            actual = None
        if actual != expected:
            return (f"parameter '{self.name}': expected {expected.name.lower()}, "
                    f'got {value!r}')
        values = value if isinstance(value, (list, tuple)) else [value]
        for v in values:
            if isinstance(v, float) and math.isnan(v):
                return f"parameter '{self.name}' = {value!r} is NaN; allowed: {self.allowed()}"
            if self.choices is not None and v not in self.choices:
                return (f"parameter '{self.name}' = {value!r} not allowed; "
                        f'allowed: {self.allowed()}')
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                if (self.min is not None and v < self.min) or \
                        (self.max is not None and v > self.max):
                    return (f"parameter '{self.name}' = {value!r} out of range; "
                            f'allowed: {self.allowed()}')
        return None


def _coerce(param: Param, value: Any) -> Any:
    """Accept an int where a double is declared (``-p x:=1`` on the command line)."""
    if param.ptype == Parameter.Type.DOUBLE and isinstance(value, int) \
            and not isinstance(value, bool):
        return float(value)
    return value


class ParamotionNode(Node):
    """Base class of every paramotion node: declared, validated parameters and sim time.

    Subclasses set ``PARAMS`` and may override :meth:`check_params` for rules that involve
    several parameters (e.g. sonar max range > detector range). Current values are available
    as ``self.params.<name>`` and are only ever updated with values that passed validation.
    ``use_sim_time`` defaults to true (the simulator owns ``/clock``) unless it is overridden.
    """

    PARAMS: tuple[Param, ...] = ()
    USE_SIM_TIME_DEFAULT = True

    def __init__(self, node_name: str, **kwargs: Any) -> None:
        overrides = list(kwargs.pop('parameter_overrides', None) or [])
        overrides = [_coerce_override(self.PARAMS, p) for p in overrides]
        super().__init__(node_name, parameter_overrides=overrides, **kwargs)
        node_name = self.get_name()  # as remapped (__node:=...): errors name this instance
        # rclpy silently ignores a value given for a parameter nobody declares (a typo in a
        # launch file or on the command line); refuse it instead, naming it.
        known = set(self._parameters) | {p.name for p in self.PARAMS}
        unknown = sorted(n for n in self._parameter_overrides
                         if n not in known and not n.startswith('qos_overrides.'))
        if unknown:
            raise ParameterError(
                f"{node_name}: unknown parameter '{unknown[0]}' (declared: "
                f"{', '.join(p.name for p in self.PARAMS)})")
        # Command-line and launch-file values (``-p real_time_factor:=4``) reach rclpy as
        # integers; give a double parameter its declared type, as for Graph overrides.
        for name, param in list(self._parameter_overrides.items()):
            self._parameter_overrides[name] = _coerce_override(self.PARAMS, param)
        if 'use_sim_time' not in self._parameter_overrides:
            self.set_parameters([Parameter('use_sim_time', value=self.USE_SIM_TIME_DEFAULT)])
        self._specs = {p.name: p for p in self.PARAMS}
        values = {}
        for spec in self.PARAMS:
            override = self._parameter_overrides.get(spec.name)
            if override is not None:
                reason = spec.check(_coerce(spec, override.value))
                if reason:
                    raise ParameterError(f'{node_name}: {reason}')
            try:
                param = self.declare_parameter(
                    spec.name, spec.default, spec.descriptor(),
                    ignore_override=override is None)
            except Exception as exc:  # rclpy raises several types for bad overrides
                raise ParameterError(f"{node_name}: parameter '{spec.name}': {exc}") from None
            values[spec.name] = param.value
        reason = self.check_params(dict(values))
        if reason:
            raise ParameterError(f'{node_name}: {reason}')
        self.params = SimpleNamespace(**values)
        self.add_on_set_parameters_callback(self._on_set_parameters)

    def destroy_node(self) -> None:
        """Destroy the node's rcl entities; in a node process stopping on a signal, within
        :data:`paramotion.shutdown.TEARDOWN_LIMIT_S` (a subclass's own clean-up, e.g. closing
        a bag, runs before it calls this and is not limited)."""
        with bounded_middleware_teardown(self.get_name()):
            return super().destroy_node()

    def check_params(self, values: dict[str, Any]) -> str | None:
        """Cross-parameter rules: return a one-line reason if ``values`` are inconsistent."""
        return None

    def on_params_changed(self, changed: dict[str, Any]) -> None:
        """Hook called after accepted parameter changes (``changed``: dict name -> value)."""

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        candidate = vars(self.params).copy()
        changed = {}
        for p in params:
            spec = self._specs.get(p.name)
            if spec is None:
                continue
            value = _coerce(spec, p.value)
            reason = spec.check(value)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
            candidate[p.name] = value
            changed[p.name] = value
        reason = self.check_params(candidate)
        if reason:
            return SetParametersResult(successful=False, reason=reason)
        # Apply after rclpy has stored them: rclpy only stores on success, so apply now.
        for name, value in changed.items():
            setattr(self.params, name, value)
        if changed:
            self.on_params_changed(changed)
        return SetParametersResult(successful=True)


def _coerce_override(specs: Sequence[Param], param: Parameter) -> Parameter:
    """Give a double parameter override passed as an int the double type it is declared with."""
    for spec in specs:
        if spec.name == param.name and param.type_ == Parameter.Type.INTEGER \
                and spec.ptype == Parameter.Type.DOUBLE:
            return Parameter(param.name, value=float(param.value))
    return param


def overrides_from_dict(values: Mapping[str, Any]) -> list[Parameter]:
    """Turn ``{'name': value}`` into a list of rclpy ``Parameter`` overrides."""
    return [Parameter(name, value=value) for name, value in values.items()]


def run_node(node_cls: Callable[[], Node], args: Sequence[str] | None = None) -> NoReturn:
    """Standard Jazzy ``main()`` body: init, spin, clean shutdown; one-line parameter errors.

    The first SIGINT or SIGTERM stops the node; later ones (a terminal Ctrl-C under launch
    sends two) are absorbed, so clean-up (``destroy_node``: a recorder closing its bag) always
    finishes, and the process then exits 0 at once (:func:`paramotion.shutdown.exit_now`).
    """
    signals = ShutdownSignals().install()   # before rclpy.init: rclpy's handler chains to it
    try:
        _run_node(node_cls, args, signals)
    finally:
        signals.finish()
    exit_now(0)


def _run_node(node_cls: Callable[[], Node], args: Sequence[str] | None,
              signals: ShutdownSignals) -> None:
    node = watchdog = waker = None
    try:
        kind = node_executor_kind()
        # The events and waitset executors are spun in 0.1 s slices that stop once a signal
        # has arrived: rclpy's handler stays out (it would shut the context down under a
        # running callback, which the events executor logs as a FATAL error), and they need
        # no guard condition of a waker. rclpy's own executor is stopped by rclpy's handler
        # between callbacks.
        events = kind != 'single_threaded'
        rclpy.init(args=args, signal_handler_options=(
            SignalHandlerOptions.NO if events else signals.rclpy_options()))
        node = node_cls()
        # A node on sim time in its own process warns once if its simulator stops.
        watchdog = attach_clock_watchdog(node)
        waker = None if events else ShutdownWaker(node)
        signals.spinning()
        spin_node(node, kind, stop=lambda: signals.requested)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (RCLError, RuntimeError):
        # Ctrl-C shut the context down while the executor was inside rcl: a callback
        # publishing (RCLError), or a subscription's take_message, whose handle the shutdown
        # invalidated (pybind11 then raises a plain RuntimeError, "Unable to convert call
        # argument '0' to Python object"). A clean stop, not a crash. The same errors with the
        # context still valid are real and re-raised.
        if rclpy.ok():
            raise
    except UserError as exc:  # bad parameter, bad input file named by a parameter
        print(f'error: {exc}', file=sys.stderr)
        sys.exit(2)
    finally:
        if waker is not None:
            waker.stop()
        if watchdog is not None:
            watchdog.stop()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


__all__ = ['Param', 'ParamotionNode', 'ParameterType', 'overrides_from_dict', 'run_node']
