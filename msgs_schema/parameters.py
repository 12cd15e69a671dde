"""The node's parameter schema: node parameters plus the tissue schema, and their validation.

One list of :class:`ParamSpec` (name, type, default, unit, description, bounds). The node
declares ROS parameters with descriptors from it, ``config/*.yaml`` files use these names
under ``ros__parameters``, and :func:`validate_parameters` validates a full dotted dict into a
frozen :class:`NodeParams` and the checked tissue values (which
:func:`skin_sim_node.model.config.build_config` turns into the model's config). Imports no ROS code.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import field, make_dataclass, replace
from typing import TYPE_CHECKING, Any

from .spec import ConfigError, ParamSpec, check_names, unknown_name
from .tissue import TISSUE_PARAMETERS, tissue_defaults

NODE_NAME = "skin_sim_node"
"""The haptic server's node name: its parameter services, and the top key of ``config/*.yaml``."""

TISSUE_PREFIX = "tissue."
"""The prefix the node declares the tissue parameters with."""


NODE_PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec(
        "rate_hz", float, 1000.0, "Hz", "haptic loop rate; 1 kHz is the haptics norm (Phantom servo loop)",
        min=10.0, max=20000.0,
    ),
    ParamSpec(
        "display_rate_hz", float, 60.0, "Hz", "height map / mesh publish rate (a display refresh rate)",
        min=0.0, max=1000.0, min_exclusive=False,
    ),
    ParamSpec(
        "watchdog_s", float, 0.05, "s",
        "input age after which the published force goes to zero (the tissue keeps its state, stall_hold_s): 50 ticks "
        "at 1 kHz, well past DDS jitter yet shorter than a hand can react to (~0.1 s)", min=0.001, max=10.0,
    ),
    ParamSpec(
        "stall_hold_s", float, 2.0, "s",
        "how long a stall in the tool input keeps the tissue's state (a needle's track and ruptures, viscoelastic "
        "arms, friction anchor, patch) with the tool held at its last pose; past it the tool is taken as gone, the "
        "tissue is released and the next pose restarts contact (0: at the watchdog). 2 s: 10 x the longest stall "
        "measured over DDS on 2 cores (189 ms, issue 31), and 7 time constants of the slow viscoelastic arm "
        "(0.28 s), which a held tissue has relaxed by then", min=0.0, max=3600.0, min_exclusive=False,
    ),
    ParamSpec(
        "max_stamp_age_s", float, 1.0, "s",
        "reject poses whose stamp differs from the node clock by more than this (0 disables)", min=0.0, max=3600.0,
        min_exclusive=False,
    ),
    ParamSpec(
        "max_force_n", float, 10.0, "N",
        "node-side force clamp; device limits (3.3 N for a Touch) are applied by the bridge", min=0.0, max=1000.0,
    ),
    ParamSpec(
        "max_force_rate_n_per_s", float, 1000.0, "N/s",
        "bound on the force's rate of change (0 disables): the fastest rise the default tissue gives a 0.1 m/s probing "
        "press (epidermis k = 9.7 kN/m: ~1000 N/s) passes, while a step from an edge, teleport or fast stab is spread "
        "over ticks (3.3 N over 3.3 ms); on the pose stamps (the model's clock), with a 1 ms allowance. See "
        "docs/stability.md",
        min=0.0, max=1e6, min_exclusive=False,
    ),
    ParamSpec(
        "teleport_distance_m", float, 0.02, "m",
        "a pose jump larger than this between samples restarts contact (20 mm: 20x a 1 m/s hand at 1 kHz)", min=0.0, max=10.0,
    ),
    ParamSpec(
        "workspace_radius_m", float, 1.0, "m",
        "reject a tool pose farther than this from the tissue origin (counted, logged once; the tissue is untouched): "
        "the largest desktop haptic devices reach about 0.42 m from their centre (Phantom Premium 3.0, 838 mm wide), "
        "so a pose beyond 1 m is a fault, not a hand", min=0.0, max=1000.0,
    ),
    ParamSpec(
        "max_tool_speed_m_s", float, 3.0, "m/s",
        "speed cap of the velocity estimate; faster apparent motion is a teleport (hands rarely exceed 2 m/s)", min=0.0,
        max=100.0,
    ),
    ParamSpec(
        "twist_max_skew_s", float, 0.005, "s",
        "use the twist topic when its stamp is within this of the pose's, else differentiate poses", min=0.0, max=1.0,
        min_exclusive=False,
    ),
    ParamSpec(
        "rate_policy", str, "follow", "-",
        "follow: input mode answers at rate_hz while the machine holds it, steps down the ladder of halves to "
        "min_rate_hz (at once to the rung the answers it made would hold) while it does not (missed or late answers; "
        "diagnostics and the log say why), and back up once the lower rate has held; "
        "the bridge forwards poses at the rate announced in each contact model and renders it in between (a node with "
        "input_queue_depth above 1 answers every sample: fixed). fixed: rate_hz always",
        choices=("follow", "fixed"),
    ),
    ParamSpec(
        "min_rate_hz", float, 125.0, "Hz",
        "the lowest rate the follow policy steps down to: at 125 Hz (8 ms) a 0.25 m/s stroke stays inside the contact "
        "model's 2 mm validity radius between answers, and its 50 ms time to live spans six of them",
        min=1.0, max=20000.0,
    ),
    ParamSpec(
        "fallback_rate_hz", float, 100.0, "Hz",
        "input mode: clock that ticks when no pose came for 1.5 of its periods (watchdog, relaxation); the "
        "modal integrator is exact for any dt, and a 1 kHz wake-up only contends for the GIL with pose callbacks",
        min=1.0, max=20000.0,
    ),
    ParamSpec(
        "input_queue_depth", int, 1, "1",
        "pose/twist reader history (read at start): 1 answers the newest sample only (lowest latency, "
        "for live haptics); more lets a node that was stalled answer every sample in order "
        "(live replay uses 500), at the cost of a latency tail",
        min=1, max=1000, min_exclusive=False, read_only=True,
    ),
    ParamSpec("tissue_frame", str, "tissue", "-", "frame_id the tool pose must carry"),
    ParamSpec(
        "loop_mode", str, "input", "-",
        "input: tick on every pose (lowest latency) with a rate_hz fallback clock; timer: fixed rate_hz only",
        choices=("input", "timer"),
    ),
    ParamSpec("publish_mesh", bool, True, "-", "publish the RViz mesh marker at display rate"),
    ParamSpec(
        "mesh_stride", int, 4, "1",
        "grid cells per mesh vertex in the deformed region (4: ~2 ms per mesh after a 2.5 mm press, 2026-12-05)",
        min=1, max=64, min_exclusive=False,
    ),
    ParamSpec(
        "mesh_rate_hz", float, 5.0, "Hz",
        "mesh marker rate: rclpy holds a Python object per vertex and the GIL while it fills them, so it is kept low",
        min=0.0, max=100.0, min_exclusive=False,
    ),
    ParamSpec("diagnostics_period_s", float, 1.0, "s", "diagnostics publish period", min=0.05, max=60.0),
    ParamSpec(
        "idle_heartbeat_hz", float, 0.0, "Hz",
        "lod idle: while the tissue is at rest and untouched (no kernel work), publish wrench and contact at most "
        "at this rate, e.g. 100 (10 ms: five beats within the bridge's 50 ms wrench watchdog). Default 0: every "
        "pose is answered, the one-wrench-per-pose contract that live replay and its tests rely on",
        min=0.0, max=20000.0, min_exclusive=False,
    ),
    ParamSpec(
        "display_on_change", bool, True, "-",
        "lod: snapshot the model for the display only when it changed, and rebuild the grid only when it moved "
        "by more than tissue.lod.tolerance_m (at most at display_rate_hz); false rebuilds every display frame",
    ),
    # haptic timing levers (read at start; measured in docs/performance_rate.md)
    ParamSpec(
        "rt_priority", int, 50, "1",
        "SCHED_FIFO priority of the haptic threads, 1-99 (0: normal scheduling). 50 is ros2_control's controller "
        "manager default (a busy process at normal priority cannot hold the haptic path off the CPU); it needs root, "
        "CAP_SYS_NICE or an rtprio limit, and when refused the node says so in one line and runs at normal priority. "
        "Every haptic thread blocks on I/O or a deadline: none spins",
        min=0, max=99, min_exclusive=False, read_only=True,
    ),
    ParamSpec(
        "rt_scope", str, "process", "-",
        "threads that get SCHED_FIFO: haptic (the tick clock and the executor that runs pose callbacks, at "
        "rt_priority) or process (also every other thread at one less: the DDS receive threads that deliver the "
        "poses are on the input-mode path)",
        choices=("haptic", "process"), read_only=True,
    ),
    ParamSpec(
        "haptic_cpu", int, -1, "1", "pin the haptic clock thread to this CPU (-1: no pinning)",
        min=-1, max=1023, min_exclusive=False, read_only=True,
    ),
    ParamSpec(
        "spin_tail_us", float, 0.0, "us",
        "busy-wait this long before each haptic deadline instead of sleeping (0: sleep all the way)", min=0.0, max=1000.0,
        min_exclusive=False, read_only=True,
    ),
    # hands (issue 32): a second tool on the same tissue, each hand's topics under its own namespace
    ParamSpec(
        "hand_ns", str, "", "-",
        "namespace of the (first) hand's tool topics, relative to the node's: '' keeps the single-tool names "
        "(tool/pose, tool/wrench, ...); 'right' gives right/tool/pose, ... (msgs_schema/topics.py: HAND_TOPICS)",
        read_only=True,
    ),
    ParamSpec(
        "second_hand_ns", str, "", "-",
        "namespace of a second hand's tool topics ('' : no second hand). Its tool presses the same tissue: each tool's "
        "chain acts at a surface lowered by the other's deflection (skin_sim_node/tools/hands.py); at most 2 hands",
        read_only=True,
    ),
    ParamSpec(
        "second_tool_shape", str, "flat", "-",
        "the second hand's tool, as tissue.tool.shape: a finger is a 'flat' pad (the needle takes tissue.needle.*)",
        choices=("flat", "sphere", "needle"), read_only=True,
    ),
    ParamSpec(
        "second_tool_radius_m", float, 0.005, "m",
        "the second hand's tool radius, as tissue.tool.radius_m. Default a fingertip pad pressed flat, 10 mm across "
        "(stated choice: narrower than an adult index fingertip, about 15 mm wide, whose rounded pulp meets the skin "
        "over less than its width at anchoring forces of about 1 N)",
        min=0.0, max=0.03, read_only=True,
    ),
    ParamSpec(
        "precise_sleep", bool, True, "-",
        "sleep to each deadline with clock_nanosleep(TIMER_ABSTIME), GIL released; false: time.sleep(remaining)", read_only=True,
    ),
)  # fmt: skip

ALL_PARAMETERS: tuple[ParamSpec, ...] = NODE_PARAMETERS + tuple(
    replace(s, name=TISSUE_PREFIX + s.name) for s in TISSUE_PARAMETERS
)
"""Every node parameter as the node declares it (tissue parameters with :data:`TISSUE_PREFIX`)."""
SPEC_BY_NAME = {s.name: s for s in ALL_PARAMETERS}
"""The one lookup of a parameter's spec, by its declared name."""


SESSION_ONLY_PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec(
        "max_dt_s", float, 0.1, "s",
        "longest interval one tick advances the model (a stalled caller does not jump the tissue ahead): "
        "100 ticks at 1 kHz, twice the default watchdog_s", min=0.0, max=10.0,
    ),
    ParamSpec(
        "max_future_s", float, 0.05, "s",
        "a pose stamp this far ahead of the node clock is rejected (clock skew allowance, as watchdog_s)", min=0.0,
        max=3600.0, min_exclusive=False,
    ),
    ParamSpec(
        "resync_after", int, 50, "1",
        "this many consecutive backwards stamps: accept the new time line (a restarted publisher; 50 ms at 1 kHz)",
        min=1, max=100000, min_exclusive=False,
    ),
)  # fmt: skip
"""Session limits that are not node parameters (the session's own; see :class:`SessionParams`)."""

SESSION_KEYS = (
    "tissue_frame", "watchdog_s", "stall_hold_s", "max_stamp_age_s", "max_force_n", "teleport_distance_m", "workspace_radius_m",
    "max_tool_speed_m_s",
    "twist_max_skew_s", "max_force_rate_n_per_s",
)  # fmt: skip
"""The node parameters the haptic session reads (input checks and force limits)."""

READ_ONLY = tuple(s.name for s in NODE_PARAMETERS if s.read_only)
"""Parameters read once at start: declared read-only, so a live set is refused with rclpy's reason."""


def params_class(name: str, specs: tuple[ParamSpec, ...], doc: str, namespace: dict | None = None) -> type:
    """A frozen dataclass with one field per spec (its type and default): the schema's view, not a retyped copy."""
    cls = make_dataclass(name, [(s.name, s.type, field(default=s.default)) for s in specs], frozen=True, namespace=namespace)
    cls.__module__ = __name__
    cls.__doc__ = doc
    return cls


SESSION_PARAMETERS: tuple[ParamSpec, ...] = tuple(s for s in NODE_PARAMETERS if s.name in SESSION_KEYS) + SESSION_ONLY_PARAMETERS


class NodeParamsFields:
    """The static view of :class:`NodeParams` (one annotation per spec; tests/test_architecture.py checks it against
    the specs): what mypy sees, the class made from the specs at run time is what runs."""

    rate_hz: float
    display_rate_hz: float
    watchdog_s: float
    stall_hold_s: float
    max_stamp_age_s: float
    max_force_n: float
    max_force_rate_n_per_s: float
    teleport_distance_m: float
    workspace_radius_m: float
    max_tool_speed_m_s: float
    twist_max_skew_s: float
    rate_policy: str
    min_rate_hz: float
    fallback_rate_hz: float
    input_queue_depth: int
    tissue_frame: str
    loop_mode: str
    publish_mesh: bool
    mesh_stride: int
    mesh_rate_hz: float
    diagnostics_period_s: float
    idle_heartbeat_hz: float
    display_on_change: bool
    rt_priority: int
    rt_scope: str
    haptic_cpu: int
    spin_tail_us: float
    hand_ns: str
    second_hand_ns: str
    second_tool_shape: str
    second_tool_radius_m: float
    precise_sleep: bool

    def __init__(self, **values: Any) -> None: ...


class SessionParamsFields:
    """The static view of :class:`SessionParams` (one annotation per spec; tests/test_architecture.py checks it against
    the specs): what mypy sees, the class made from the specs at run time is what runs."""

    watchdog_s: float
    stall_hold_s: float
    max_stamp_age_s: float
    max_force_n: float
    max_force_rate_n_per_s: float
    teleport_distance_m: float
    workspace_radius_m: float
    max_tool_speed_m_s: float
    twist_max_skew_s: float
    tissue_frame: str
    max_dt_s: float
    max_future_s: float
    resync_after: int

    def __init__(self, **values: Any) -> None: ...


if TYPE_CHECKING:  # the classes made at run time from the specs have no static fields: mypy sees their typed views
    NodeParams = NodeParamsFields
    SessionParams = SessionParamsFields
else:
    NodeParams = params_class(
        "NodeParams", NODE_PARAMETERS, "The node's non-tissue parameters, read once (fields: NODE_PARAMETERS)."
    )
    SessionParams = params_class(
        "SessionParams",
        SESSION_PARAMETERS,
        "Input and safety parameters of the haptic session (fields: SESSION_PARAMETERS; sources in their descriptions).",
    )


def session_params(node_params, **overrides) -> SessionParams:
    """The :class:`SessionParams` view of a :class:`NodeParams` (the one mapping; offline replay overrides the stamp age)."""
    return SessionParams(**({k: getattr(node_params, k) for k in SESSION_KEYS} | overrides))


def check_value(name: str, value: Any) -> Any:
    """Coerce and bound-check one parameter by its declared name.

    Parameters
    ----------
    name : str
        Declared name (tissue parameters with the ``tissue.`` prefix).
    value : Any

    Returns
    -------
    Any
        The value as the spec's type.

    Raises
    ------
    ConfigError
        An unknown name or a bad value, with the reason.
    """
    spec = SPEC_BY_NAME.get(name)
    if spec is None:
        raise ConfigError(unknown_name(name, SPEC_BY_NAME))
    return spec.check(value)


def check_overrides(overrides: Mapping[str, Any], builtin: Iterable[str] = ()) -> dict[str, Any]:
    """The node's start-up overrides (parameter files and ``-p``), every name and value checked against the contract.

    Parameters
    ----------
    overrides : mapping
        Declared name -> value, as rcl resolved them for the node (every file entry that matches it, every ``-p``).
    builtin : iterable of str
        Names the ROS client library declares itself (``use_sim_time``, ...): accepted and left out of the result.

    Returns
    -------
    dict
        Declared name -> the value as its spec's type (an integer given for a float is a float).

    Raises
    ------
    ConfigError
        Unknown names (each with the closest valid name) or the first bad value, in one line.
    """
    builtin = set(builtin)
    check_names(overrides, set(SPEC_BY_NAME) | builtin)
    return {name: check_value(name, value) for name, value in overrides.items() if name not in builtin}


def node_params_from_flat(flat: Mapping[str, Any]) -> NodeParams:
    """The :class:`NodeParams` of a dotted parameter dict (its ``tissue.`` names are left out).

    Parameters
    ----------
    flat : mapping
        Declared name -> value; missing node parameters take their defaults.

    Returns
    -------
    NodeParams

    Raises
    ------
    ConfigError
        An unknown name or a bad value, with the reason.
    """
    values = {s.name: s.default for s in NODE_PARAMETERS}
    for name, value in flat.items():
        if not name.startswith(TISSUE_PREFIX):
            values[name] = check_value(name, value)
    check_hands(values["hand_ns"], values["second_hand_ns"])
    return NodeParams(**{s.name: values[s.name] for s in NODE_PARAMETERS})


HAND_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
"""A hand's namespace: one ROS name token (a letter, then letters, digits, underscores), so ``<hand>/tool/pose`` is a
valid relative topic name."""


def check_hands(hand_ns: str, second_hand_ns: str) -> None:
    """The hands' namespaces: each '' or one name token, and two hands named apart.

    Parameters
    ----------
    hand_ns, second_hand_ns : str

    Raises
    ------
    ConfigError
        With the reason.
    """
    for name, ns in (("hand_ns", hand_ns), ("second_hand_ns", second_hand_ns)):
        if ns and not HAND_NAME.fullmatch(ns):
            raise ConfigError(f"{name} = {ns!r}: a hand's namespace is one name token (a letter, then letters, digits, _)")
    if second_hand_ns and second_hand_ns == hand_ns:
        raise ConfigError(f"second_hand_ns = {second_hand_ns!r}: the two hands need different namespaces (hand_ns is the same)")


def tissue_part(flat: Mapping[str, Any], prefix: str = TISSUE_PREFIX) -> dict[str, Any]:
    """The tissue parameters of a node's dotted parameter dict, prefix stripped.

    Parameters
    ----------
    flat : mapping
        Declared name -> value.
    prefix : str

    Returns
    -------
    dict
    """
    return {k[len(prefix) :]: v for k, v in flat.items() if k.startswith(prefix)}


def check_tissue(values: Mapping[str, Any]) -> dict[str, Any]:
    """Every tissue parameter, checked: ``values`` coerced and bound-checked, the others at their defaults.

    Parameters
    ----------
    values : mapping
        Dotted tissue name without the ``tissue.`` prefix -> value.

    Returns
    -------
    dict
        Every tissue parameter (no prefix) -> its checked value: what
        :func:`skin_sim_node.model.config.build_config` takes.

    Raises
    ------
    ConfigError
        Unknown names, wrong types, out-of-bound values; the message names the parameter without the prefix.
    """
    tissue_names = [s.name for s in TISSUE_PARAMETERS]
    check_names(values, tissue_names)
    flat = tissue_defaults()
    for name, value in values.items():
        flat[name] = SPEC_BY_NAME[TISSUE_PREFIX + name].check(value, label=name)
    return flat


def validate_parameters(flat: Mapping[str, Any], changed: Iterable[str] = ()) -> tuple[NodeParams, dict[str, Any]]:
    """Validate a full dotted node parameter dict: the node parameters and the tissue values.

    Parameters
    ----------
    flat : mapping
        Declared name -> value (a parameter file's, or the node's after a set).
    changed : iterable of str
        Names checked first against their declared spec, so that the reason for a rejected set names the
        parameter as the node declares it (``tissue.`` prefix kept).

    Returns
    -------
    node_params : NodeParams
    tissue : dict
        The checked tissue values (:func:`check_tissue`); the model's own geometry checks follow when
        :func:`skin_sim_node.model.config.build_config` builds its config from them.

    Raises
    ------
    ConfigError
        With the reason.
    """
    check_names(flat, SPEC_BY_NAME)  # every unknown name at once, each with its closest valid name
    for name in changed:
        check_value(name, flat[name])
    return node_params_from_flat(flat), check_tissue(tissue_part(flat))
