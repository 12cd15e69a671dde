"""The shared base of the device-side nodes (bridge, simulated device, mock tool), ros2/demos style.

Each node is a module-level :class:`rclpy.node.Node` subclass that lists its parameters once in
:attr:`DeviceNode.PARAMS`. From that table the base declares the ROS parameters (all read-only:
they are read once at start, so a live change cannot silently do nothing) and builds the
command line (``skin-sim bridge --max-force-n 2 ...``, each option with its description, unit and
default); ``--ros-args -p name:=value`` still wins over both. :meth:`DeviceNode.main` parses the
command line and runs the node with :func:`skin_sim_node.ros_util.run_nodes`.
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from msgs_schema.spec import ConfigError, ParamSpec, check_names

from ..ros_util import LoopTiming, PeriodicLoop, run_nodes, set_pid_realtime
from .mapping import parse_vec3

HOUSEKEEPING_PERIOD_S = 0.05
"""Period of a timer in the loop-thread nodes (mock tool, simulated device). It wakes the executor at least
every 50 ms even when no message arrives, and it ends the process from the executor thread when the script
is done (``rclpy.try_shutdown``)."""

EXECUTOR = "events"
"""rclpy executor for :func:`run_nodes` (which drives it with ``spin_once(timeout)``: far less CPU per
callback than the single-threaded executor; its ``spin()`` ignores context shutdown with the 7.1.6 wheels)."""


@dataclass(frozen=True)
class Param:
    """One start-time parameter of a device node.

    ``cli``: the command-line option (``None``: ``--`` plus the name with dashes; ``""``: none).
    ``lo``/``hi``: the ROS descriptor's range (numbers only; both or neither). ``choices``: allowed strings.
    ``presets``: per value of this parameter, other parameters it sets unless they are given (command line or ROS).
    """

    name: str
    default: Any
    description: str
    lo: float | None = None
    hi: float | None = None
    choices: tuple[str, ...] = ()
    cli: str | None = None
    presets: dict[str, dict[str, Any]] = field(default_factory=dict)


def check_param(spec: Param, value: Any) -> Any:
    """``value`` checked against a :class:`Param` by the contract's own check (:meth:`msgs_schema.spec.ParamSpec.check`:
    type, finite, the inclusive range ``lo``-``hi``, the choices); a 3-vector's components as floats.

    Parameters
    ----------
    spec : Param
    value : Any

    Returns
    -------
    Any
        The value as the default's type (an integer given for a float is a float).

    Raises
    ------
    ConfigError
        With the reason, naming the parameter.
    """
    if isinstance(spec.default, list):
        if not isinstance(value, (list, tuple)) or len(value) != len(spec.default):
            raise ConfigError(f"{spec.name}: expected {len(spec.default)} numbers, got {value!r}")
        item = ParamSpec(spec.name, float, 0.0, "-", spec.description)
        return [item.check(c) for c in value]
    kind = type(spec.default)
    return ParamSpec(
        spec.name, kind, spec.default, "-", spec.description, min=spec.lo, max=spec.hi, min_exclusive=False, choices=spec.choices
    ).check(value)


def publish_while_ok(node, pub, msg) -> bool:
    """Publish ``msg``; if rclpy was shut down meanwhile (SIGINT/SIGTERM mid-callback), drop it quietly.

    Returns True if published. Errors while the context is still valid propagate.
    """
    try:
        pub.publish(msg)
        return True
    except Exception:
        if node.context.ok():
            raise
        return False


class DeviceNode(Node):
    """Base: declares :attr:`PARAMS` from ``overrides`` and exposes the values as :attr:`p`.

    Subclasses set :attr:`NODE_NAME`, :attr:`PROG` (``skin-sim <command>``), :attr:`PARAMS`, and may
    override :meth:`add_arguments` / :meth:`overrides_from` for options that are not parameters.
    """

    NODE_NAME = "device_node"
    PROG = "skin-sim"
    DESCRIPTION = ""
    PARAMS: tuple[Param, ...] = ()
    ROS_ARGS: list[str] = []  # the process's --ros-args (set by main), for a node that opens a second context

    def __init__(self, overrides: dict | None = None, **kwargs):
        super().__init__(self.NODE_NAME, **kwargs)
        # The command line's values, then every override rcl resolved for this node (file entries, -p; rclpy keeps
        # them in Node._parameter_overrides, with no public accessor), checked before anything is declared: rclpy would
        # ignore an unknown name silently and answer a bad value with a traceback.
        self._builtin_parameters = frozenset(self._parameters)
        specs = {s.name: s for s in self.PARAMS}
        ros = {n: p.value for n, p in self._parameter_overrides.items() if n not in self._builtin_parameters}
        check_names(ros, specs)
        given = {n: check_param(specs[n], v) for n, v in ((overrides or {}) | ros).items()}
        for spec in (s for s in self.PARAMS if s.presets):  # a preset fills in what was not given
            for name, value in spec.presets.get(given.get(spec.name, spec.default), {}).items():
                given.setdefault(name, check_param(specs[name], value))
        values = {}
        for spec in self.PARAMS:
            default = given.get(spec.name, spec.default)
            d = ParameterDescriptor(read_only=True, description=spec.description)
            lo, hi = spec.lo, spec.hi
            if lo is not None and hi is not None and isinstance(spec.default, float):
                d.floating_point_range = [FloatingPointRange(from_value=float(lo), to_value=float(hi))]
            elif lo is not None and hi is not None and isinstance(spec.default, int) and not isinstance(spec.default, bool):
                d.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi))]
            self.declare_parameter(spec.name, default, d, ignore_override=True)
            values[spec.name] = self.get_parameter(spec.name).value
        self.p = SimpleNamespace(**values)

    def set_parameters_atomically(self, parameter_list: list[Parameter]) -> SetParametersResult:
        """A live set: an unknown name is refused with the reason start-up gives (the closest valid name); every
        parameter here is read-only, so rclpy refuses the rest with its read-only reason."""
        try:
            check_names((p.name for p in parameter_list), {s.name for s in self.PARAMS} | self._builtin_parameters)
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return super().set_parameters_atomically(parameter_list)

    def say(self, text: str) -> None:
        """Log at info; once rclpy has shut down (Ctrl-C), print instead of failing to reach rosout."""
        if self.context.ok():
            self.get_logger().info(text)
        else:
            print(f"[{self.get_name()}] {text}", flush=True)

    # --- command line -------------------------------------------------------------------
    @classmethod
    def parser(cls) -> argparse.ArgumentParser:
        """The command line: one option per :attr:`PARAMS` entry (description, unit, default), then :meth:`add_arguments`."""
        ap = argparse.ArgumentParser(
            prog=cls.PROG,
            description=cls.DESCRIPTION,
            epilog="Every option is also a read-only ROS parameter: --ros-args -p name:=value overrides it.",
        )
        for spec in cls.PARAMS:
            if spec.cli == "":
                continue
            flag = spec.cli or "--" + spec.name.replace("_", "-")
            help_text = f"{spec.description} (default {spec.default!r})"
            if isinstance(spec.default, bool):
                continue  # booleans get explicit on/off flags in add_arguments
            if spec.choices:
                ap.add_argument(flag, dest=spec.name, choices=spec.choices, help=help_text)
            elif isinstance(spec.default, list):
                ap.add_argument(flag, dest=spec.name, type=parse_vec3, help=help_text + "; 'x y z'")
            else:
                ap.add_argument(flag, dest=spec.name, type=type(spec.default), help=help_text)
        cls.add_arguments(ap)
        return ap

    @classmethod
    def add_arguments(cls, ap: argparse.ArgumentParser) -> None:
        """Options that are not one-to-one parameters."""

    @classmethod
    def overrides_from(cls, opts: argparse.Namespace) -> dict:
        """Parameter overrides from the parsed options (the table's options that were given)."""
        names = {s.name for s in cls.PARAMS}
        return {k: v for k, v in vars(opts).items() if k in names and v is not None}

    @classmethod
    def main(cls, argv=None) -> int:
        """``skin-sim <command> [options] [--ros-args ...]``: parse, then run the node until Ctrl-C/SIGTERM."""
        argv = sys.argv[1:] if argv is None else list(argv)
        ros = argv[argv.index("--ros-args") :] if "--ros-args" in argv else []
        own = argv[: len(argv) - len(ros)]
        opts = cls.parser().parse_args(own)
        early = cls.before_start(opts)
        if early is not None:
            return early
        overrides = cls.overrides_from(opts)
        cls.ROS_ARGS = ros
        return run_nodes(cls.factories(overrides), args=ros, executor=EXECUTOR)

    @classmethod
    def factories(cls, overrides: dict) -> list:
        """The nodes this command runs in its process, in build order (default: this node alone)."""
        return [lambda: cls(overrides)]

    @classmethod
    def before_start(cls, opts: argparse.Namespace) -> int | None:
        """Checks or actions before rclpy starts; an int ends the command with that code."""
        return None


class ScriptedNode(DeviceNode):
    """A device node that plays a script in its own periodic loop thread (simulated device, mock tool).

    Adds ``--loop`` (``repeat`` 0) and ``--no-exit`` (``exit_when_done`` false), runs ``tick(now_ns, elapsed_ns)``
    every ``period_ns`` in a :class:`skin_sim_node.ros_util.PeriodicLoop`, and ends the process from the executor
    thread once :meth:`finish` was called (a housekeeping timer, see :data:`HOUSEKEEPING_PERIOD_S`).
    """

    @classmethod
    def add_arguments(cls, ap) -> None:
        """``--loop`` (repeat the script forever) and ``--no-exit`` (hold the end pose)."""
        ap.add_argument("--loop", action="store_true", help="loop the script forever (repeat 0)")
        ap.add_argument("--no-exit", action="store_true", help="keep holding the end pose instead of exiting")

    @classmethod
    def overrides_from(cls, opts) -> dict:
        """The parameter overrides of ``--loop`` and ``--no-exit`` on top of the base's."""
        o = super().overrides_from(opts)
        if opts.loop:
            o["repeat"] = 0
        if opts.no_exit:
            o["exit_when_done"] = False
        return o

    def start_loop(self, period_ns: int, tick, name: str, rt_priority: int = 0) -> None:
        """Run ``tick`` every ``period_ns`` on a :class:`~skin_sim_node.ros_util.PeriodicLoop` thread (at SCHED_FIFO
        ``rt_priority`` where allowed: one warning line when refused); start housekeeping."""
        self.finished = False
        if rt_priority > 1:  # every thread now (DDS, the executor) one below the loop: no priority inversion through
            # the GIL (a normal-priority thread holding it, preempted by a busy process, would hold the loop up)
            why = set_pid_realtime(os.getpid(), rt_priority - 1, skip_own=True)
            if why:
                self.get_logger().warning(why)
        self._loop = PeriodicLoop(
            period_ns, tick, name=name, timing=LoopTiming(rt_priority=rt_priority), on_warning=self.get_logger().warning
        )
        self.create_timer(HOUSEKEEPING_PERIOD_S, self._housekeeping)
        self._loop.start()

    def housekeeping(self) -> None:
        """Executor-thread work every :data:`HOUSEKEEPING_PERIOD_S` (override and call super)."""

    def _housekeeping(self) -> None:
        self.housekeeping()
        if self.finished:
            rclpy.try_shutdown(context=self.context)

    def finish(self, message: str) -> None:
        """From inside the loop thread: the script is done; stop the loop (no join) and let the process end."""
        self.finished = True
        self.say(message)
        self._loop.stop()

    def stop(self) -> None:
        """Stop the periodic loop (joins its thread)."""
        self._loop.stop()
