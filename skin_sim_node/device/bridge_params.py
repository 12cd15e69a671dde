"""The bridge's parameters (``skin-sim bridge``'s options and read-only ROS parameters), each with its unit, default and
reason: one table, :data:`BRIDGE_PARAMS`, that :class:`skin_sim_node.device.bridge.BridgeNode` declares."""

from __future__ import annotations

from .base import Param
from .mapping import CONVENTIONS, DEFAULTS, DEVICE_PRESETS, TOUCH_MAX_DAMPING_N_S_PER_M, TOUCH_MAX_STIFFNESS_N_PER_M
from .render import FADE_S
from .stylus import DeviceParams

SOURCES = ("model", "wrench")
STABILISERS = ("none", "passivity")
FRICTION_RENDERS = ("law", "linear")
RT_PRIORITY = 80
"""SCHED_FIFO priority of the device path (the executor thread that renders each device pose and the device-side
DDS threads); the node link's threads run one below. 80 sits above the kernel's threaded IRQs (50 on PREEMPT_RT),
as the node's ``rt_priority`` documents for servo loops."""

CPU_LATENCY_US = 0
"""The PM QoS CPU wake-up latency the bridge holds while it runs (``/dev/cpu_dma_latency``, us). 0 is what cyclictest
holds while it measures: an idle CPU polls instead of entering a state it must be woken from. On this project's
2-core VMs the deeper state is a halt that exits to the host (the haltpoll cpuidle driver), and the device path wakes
2000 times a second per device: alternating two-hand device benches with and without it, 4 pairs, 2026-12-06, missed
3-9 aims against 7-10 and had 3-9 command gaps over 5 ms against 4-27 (both arms with a thread-priority trial since
reverted; docs/two_hands.md, "Session 10"). The cost: idle CPUs stay
busy polling, as the host and a laptop's battery see them."""

BRIDGE_PARAMS: tuple[Param, ...] = (
    Param(
        "device",
        "sim",
        "device preset: sim (skin-sim device, axes xyz) or touch (a Touch under sawSensablePhantom: "
        "convention crtk, axes x-zy); options given explicitly win",
        choices=tuple(DEVICE_PRESETS),
        presets=DEVICE_PRESETS,
    ),
    Param("convention", DEFAULTS["convention"], "device driver topic convention", choices=tuple(CONVENTIONS)),
    Param("device_ns", DEFAULTS["device_ns"], "namespace of the device topics (relative; '' for none)"),
    Param("offset_m", DEFAULTS["offset_m"], "tissue-frame position of the device origin (m)"),
    Param("scale", DEFAULTS["scale"], "motion scale: tissue m per device m", 1e-3, 1e3),
    Param("axes", DEFAULTS["axes"], "tissue x, y, z as signed device axes, e.g. xyz, or x-zy for a Touch base frame"),
    Param(
        "force_scale",
        DEFAULTS["force_scale"],
        "force scale: F_device = force_scale * R^T F_tissue, before the clamp (a needle's puncture peak above the "
        "clamp is flattened at scale 1; e.g. 0.6 keeps an 18 G peak, 2.7 N, under sawSensablePhantom's 2 N)",
        0.0,
        100.0,
    ),
    Param("max_force_n", DEFAULTS["max_force_n"], "device force clamp (N); Touch peak 3.3 N", 0.0, 100.0),
    Param(
        "max_stiffness_n_per_m",
        TOUCH_MAX_STIFFNESS_N_PER_M,
        "cap of the rendered stiffness at the device (N/m); Touch spec >= 1.02 N/mm on its weakest axis",
        0.0,
        1e6,
    ),
    Param(
        "max_damping_n_s_per_m",
        TOUCH_MAX_DAMPING_N_S_PER_M,
        "cap of the rendered damping at the device (N*s/m); sawSensablePhantom's largest servo damping on a Touch",
        0.0,
        1e4,
    ),
    Param(
        "friction_render",
        "law",
        "law: evaluate the contact model's friction law at the device's velocity (CRTK measured_cv) every tick; "
        "linear: f0 + K dx + D dv (D capped), as a consumer without the law",
        choices=FRICTION_RENDERS,
    ),
    Param(
        "max_friction_slope_n_s_per_m",
        0.0,
        "cap of the rendered friction law's slope at zero slip, mu F_n / v_r (N*s/m); 0: the model's own law. "
        "0.6 m / T (27 N*s/m for a 45 g stylus at 1 kHz) ends the stick chatter of a light stylus, at a render error",
        0.0,
        1e6,
    ),
    Param(
        "chatter_guard",
        "on",
        "on: while the device's tangential velocity reverses twice within 10 ms (stick on a light stylus, or "
        "velocity noise), cap the friction law's slope at the device's stable damping, 2 sin(pi/10) device_mass_kg / 1 ms",
        choices=("on", "off"),
    ),
    Param(
        "slip_speed_floor_m_s",
        0.0,
        "least regularisation speed of the rendered friction law, in the device's velocity (m/s): raise it to the "
        "noise of the driver's measured_cv near rest; 0: the model's own v_s",
        0.0,
        1.0,
    ),
    Param(
        "read_velocity",
        "auto",
        "read the driver's measured velocity (CRTK measured_cv, one more message per device tick): auto, from the first "
        "contact model whose law needs it (a damping term, or the velocity friction law: the paper form, a "
        "legacy server); the default layered model's presliding friction and the passivity controller work from "
        "positions. always; never",
        choices=("auto", "always", "never"),
    ),
    Param(
        "node_ns",
        DEFAULTS["node_ns"],
        "namespace of the node's topics (tool/pose, tool/twist, tool/contact_model, tool/wrench), e.g. /skin1; "
        "'' : the process's. Unlike -r __ns:=, it leaves the device topics where they are",
    ),
    Param(
        "rt_priority",
        RT_PRIORITY,
        "SCHED_FIFO priority of the device path, 1-99 (0: normal scheduling); refused without root/CAP_SYS_NICE",
        0,
        99,
    ),
    Param(
        "cpu_latency_us",
        CPU_LATENCY_US,
        "PM QoS CPU wake-up latency held while the bridge runs (/dev/cpu_dma_latency, us; 0: idle CPUs poll, as "
        "cyclictest holds; -1: no request); refused without root",
        -1,
        1_000_000,
    ),
    Param(
        "force_source",
        "model",
        "model: render tool/contact_model per device tick; wrench: forward tool/wrench",
        choices=SOURCES,
    ),
    Param("fade_s", FADE_S, "fade to zero when the model goes stale or the tool leaves it (s)", 1e-3, 1.0),
    Param(
        "stabiliser",
        "passivity",
        "passivity: time-domain passivity controller on the rendered force; none",
        choices=STABILISERS,
    ),
    Param("device_mass_kg", DeviceParams.mass_kg, "apparent stylus mass for the passivity controller (kg)", 1e-3, 10.0),
    Param(
        "watchdog_s",
        DEFAULTS["watchdog_s"],
        "device pose age (s) after which one zero force is sent (wrench source: also the node's wrench age)",
        1e-3,
        10.0,
    ),
    Param("watchdog_rate_hz", DEFAULTS["watchdog_rate_hz"], "watchdog check rate (Hz)", 1.0, 1e4),
    Param("device_frame", DEFAULTS["device_frame"], "frame_id of force commands; empty: the device pose's frame_id"),
    Param("restamp", DEFAULTS["restamp"], "stamp tool poses with the bridge clock instead of the driver's", cli=""),
    Param(
        "forward_twist",
        False,
        "also forward the device's measured velocity as tool/twist (one more message per forwarded pose for the "
        "bridge and the node); off: the node differentiates the poses it answers, so its force depends on the poses "
        "alone and offline replay reproduces it",
        cli="",
    ),
    Param("diagnostics_period_s", 1.0, "period of the bridge's diagnostics (s)", 0.05, 60.0),
)
