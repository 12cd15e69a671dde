"""``skin-sim``: one entry point; each subcommand is a module's ``main(argv)``."""

from __future__ import annotations

import importlib
import sys

from .startup import install_option_suggestions, node_argument_error, suggest

COMMANDS = {
    "demo": ("skin_sim_node.demo", "headless demo scene: node + bridge + simulated device, summary and picture"),
    "node": ("skin_sim_node.server.node", "run skin_sim_node (the haptic server)"),
    "bridge": ("skin_sim_node.device.bridge", "device bridge between Geomagic Touch drivers (CRTK / omni) and the node"),
    "device": ("skin_sim_node.device.sim_device", "simulated Touch device following a hand path"),
    "mock-tool": ("skin_sim_node.device.mock_tool", "scripted tool pose/twist publisher"),
    "scene": ("skin_sim_node.scenes", "start a scene as separate processes"),
    "bench": ("skin_sim_node.perf.bench_node", "node latency / rate benchmark against bare rclpy baselines"),
    "bench-model": ("skin_sim_node.perf.bench_model", "model step micro-benchmark (numba vs NumPy)"),
    "perf-lod": ("skin_sim_node.perf.lod", "node CPU in four scenes with the level-of-detail levers off and on"),
    "force-path": ("skin_sim_node.perf.force_path", "offline: device force error vs server rate, model vs hold-last (~1 min)"),
    "soak": ("skin_sim_node.perf.soak", "soak: node + bridge + simulated device at 1 kHz; memory growth and force gaps"),
    "scale": ("skin_sim_node.perf.scale", "how many 1 kHz sessions (node + bridge + device, own namespaces) one machine holds"),
    "netns-role": ("skin_sim_node.perf.netns", "netns_scale.sh helper: device side (bridge, device, observer); comparison"),
    "echo": ("skin_sim_node.perf.echo", "bare rclpy echo node (pose in, wrench out): the latency baseline"),
    "chart": ("skin_sim_node.viz.figures", "regenerate figures: chart model|validation|stability|performance"),
    "stability-loop": ("skin_sim_node.stability.haptic_loop", "haptic loop stability sweep (naive vs passivity controller)"),
    "stability-numerics": ("skin_sim_node.stability.numerics", "measured explicit solver limits vs CFL / omega*dt < 2"),
    "stability-dds": ("skin_sim_node.stability.dds_confirm", "confirm haptic-loop sweep points with real processes over DDS"),
    "record": ("skin_sim_node.bags.record", "record a scene's tool inputs and node outputs to a rosbag2 folder"),
    "replay": ("skin_sim_node.bags.replay", "replay a bag through the model offline (or --live against a node)"),
    "calibrate": ("skin_sim_node.validation.calibrate", "fit the layer springs, stiffening and foundation to the FEM or a CSV"),
    "compare": ("skin_sim_node.bags.compare", "diff two output bags with tolerances; non-zero exit when they differ"),
    "view": ("skin_sim_node.view", "live 3D view of the tissue in the browser, from the node's topics or a bag (docs/view.md)"),
}


# ``skin-sim chart TARGET``: each target's module regenerates its own docs figures.
CHART_TARGETS = {
    "model": ("skin_sim_node.viz.figures", "model figures: deformation, layers, modes (docs/figures)"),
    "validation": ("skin_sim_node.validation.charts", "FEM reference, speed-accuracy chart, calibration, Table II"),
    "stability": ("skin_sim_node.stability.charts", "numerical and haptic-loop stability maps (~6 min)"),
    "performance": ("skin_sim_node.perf.charts", "cost growth against modes and grid size"),
}


def chart_usage() -> str:
    width = max(map(len, CHART_TARGETS))
    lines = ["usage: skin-sim chart TARGET [args]   (skin-sim chart TARGET --help: its options)", "",
             "Regenerates the figures of one target in docs/figures. targets:"]  # fmt: skip
    lines += [f"  {name:<{width}}  {desc}" for name, (_, desc) in CHART_TARGETS.items()]
    return "\n".join(lines)


def chart(rest: list[str]) -> int:
    """``skin-sim chart``: dispatch to a target; without one, list the targets and regenerate nothing."""
    if not rest or rest[0] in ("-h", "--help"):
        print(chart_usage())
        return 0 if rest else 2
    if rest[0] not in CHART_TARGETS:
        print(f"skin-sim chart: error: unknown target {rest[0]!r}{suggest(rest[0], CHART_TARGETS)}; "
              f"targets: {', '.join(CHART_TARGETS)}", file=sys.stderr)  # fmt: skip
        return 2
    module = importlib.import_module(CHART_TARGETS[rest[0]][0])
    return int(module.main(rest[1:]) or 0)


def usage() -> str:
    width = max(map(len, COMMANDS))
    lines = ["usage: skin-sim COMMAND [args]", "", "commands:"]
    lines += [f"  {name:<{width}}  {desc}" for name, (_, desc) in COMMANDS.items()]
    return "\n".join(lines)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(usage())
        return 0
    cmd, rest = argv[0], argv[1:]
    install_option_suggestions()
    if cmd == "chart":
        return chart(rest)
    if cmd not in COMMANDS:
        print(f"skin-sim: error: unknown command {cmd!r}{suggest(cmd, [*COMMANDS, 'chart'])}; skin-sim --help lists "
              "the commands", file=sys.stderr)  # fmt: skip
        return 2
    if cmd == "node" and (problem := node_argument_error(rest)):
        print(f"skin-sim node: error: {problem}", file=sys.stderr)
        return 2
    module = importlib.import_module(COMMANDS[cmd][0])
    try:
        return int(module.main(rest) or 0)
    except FileNotFoundError as exc:  # a missing input file is one line, not a traceback
        print(f"skin-sim {cmd}: error: {exc.filename or exc}: no such file", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
