"""``skin-sim``: one entry point; each subcommand is a module's ``main(argv)``."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

from msgs_schema.spec import ConfigError

from .startup import install_option_suggestions, node_argument_error, suggest

COMMANDS = {
    "demo": ("skin_sim_node.demo", "headless demo scene: node + bridge + simulated device, summary and picture"),
    "node": ("skin_sim_node.server.node", "run skin_sim_node (the haptic server)"),
    "bridge": ("skin_sim_node.device.bridge", "device bridge between Geomagic Touch drivers (CRTK / omni) and the node"),
    "device": ("skin_sim_node.device.sim_device", "simulated Touch device following a hand path"),
    "mock-tool": ("skin_sim_node.device.mock_tool", "scripted tool pose/twist publisher"),
    "scene": ("skin_sim_node.scenes", "start a scene as separate processes"),
    "bench": ("skin_sim_lab.perf.bench_node", "node latency / rate benchmark against bare rclpy baselines"),
    "visco": (
        "skin_sim_lab.validation.viscoelastic",
        "offline: relaxation, creep, rate effect, recovery vs in-vivo data (~3 s)",
    ),
    "bench-model": ("skin_sim_lab.perf.bench_model", "model step micro-benchmark (numba vs NumPy)"),
    "bench-device": (
        "skin_sim_lab.perf.device_bench",
        "device benchmark: CRTK emulator at 1 kHz vs node + bridge, per phase, vs offline ground truth",
    ),
    "perf-lod": ("skin_sim_lab.perf.lod", "node CPU in four scenes with the level-of-detail levers off and on"),
    "force-path": (
        "skin_sim_lab.perf.force_path",
        "offline: device force error vs server rate, model vs hold-last (~10 s on 2 cores)",
    ),
    "friction": (
        "skin_sim_lab.perf.friction_path",
        "offline: presliding friction figures: tremor vs today's law, drag at 1/10/30 mm/s, reversal loop (~20 s)",
    ),
    "needle-angle": (
        "skin_sim_lab.validation.needle_angle",
        "offline: the needle at 90-15 deg (puncture, tip travel, force angle, skate) and its withdrawal (~10 s)",
    ),
    "stall": (
        "skin_sim_lab.validation.stall",
        "offline: a needle stalled 60/150/500 ms at each phase against the unpaused path (issue 31, ~10 s)",
    ),
    "two-punch": (
        "skin_sim_lab.validation.two_punch",
        "offline: two flat punches 4-20 mm apart on one tissue vs the 3D neo-Hookean FEM (issue 32; cached solves)",
    ),
    "two-hands": (
        "skin_sim_lab.validation.two_hands",
        "offline: a needle with an anchoring finger, two-hand passivity and the coupling's cross term (issue 32, ~20 s)",
    ),
    "needle-device": (
        "skin_sim_lab.perf.needle_device",
        "offline: needle insertion rendered at 1 kHz from a 250 Hz server vs truth and hold-last (~10 s)",
    ),
    "soak": ("skin_sim_lab.perf.soak", "soak: node + bridge + simulated device at 1 kHz; memory growth and force gaps"),
    "scale": ("skin_sim_lab.perf.scale", "how many 1 kHz sessions (node + bridge + device, own namespaces) one machine holds"),
    "netns-role": ("skin_sim_lab.perf.netns", "netns_scale.sh helper: device side (bridge, device, observer); comparison"),
    "echo": ("skin_sim_lab.perf.echo", "bare rclpy echo node (pose in, wrench out): the latency baseline"),
    "chart": ("skin_sim_lab.viz.figures", "regenerate figures: chart model|validation|stability|performance"),
    "stability-loop": ("skin_sim_lab.stability.haptic_loop", "haptic loop stability sweep (naive vs passivity controller)"),
    "stability-numerics": ("skin_sim_lab.stability.numerics", "measured explicit solver limits vs CFL / omega*dt < 2"),
    "stability-dds": ("skin_sim_lab.stability.dds_confirm", "confirm haptic-loop sweep points with real processes over DDS"),
    "record": ("skin_sim_node.bags.record", "record a scene's tool inputs and node outputs to a rosbag2 folder"),
    "replay": ("skin_sim_node.bags.replay", "replay a bag through the model offline (or --live against a node)"),
    "calibrate": ("skin_sim_lab.validation.calibrate", "fit the layer springs, stiffening and foundation to the FEM or a CSV"),
    "compare": ("skin_sim_node.bags.compare", "diff two output bags with tolerances; non-zero exit when they differ"),
    "view": ("skin_sim_node.view", "live 3D view of the tissue in the browser, from the node's topics or a bag (docs/view.md)"),
}


# ``skin-sim chart TARGET``: each target's module regenerates its own docs figures.
CHART_TARGETS = {
    "model": ("skin_sim_lab.viz.figures", "model figures: deformation, layers, modes (docs/figures)"),
    "validation": ("skin_sim_lab.validation.charts", "FEM reference, speed-accuracy chart, calibration, Table II"),
    "stability": ("skin_sim_lab.stability.charts", "numerical and haptic-loop stability maps (~1.5-2 min measured on 2 cores)"),
    "performance": ("skin_sim_lab.perf.charts", "cost growth against modes and grid size"),
}


CHART_OUT = Path("out/chart")
"""Where ``skin-sim chart TARGET`` writes unless told ``--docs`` or ``--out``: the tracked docs stay as committed."""
CHART_DOCS = {"model": "figures", "validation": "validation", "stability": "stability", "performance": "performance"}
"""The tracked docs folder of each target (``--docs``)."""


def chart_usage() -> str:
    width = max(map(len, CHART_TARGETS))
    lines = [
        "usage: skin-sim chart TARGET [--docs] [args]   (skin-sim chart TARGET --help: its options)",
        "",
        f"Regenerates the figures of one target into {CHART_OUT}/TARGET, or with --docs into the tracked",
        "docs folder (docs/figures, docs/validation, docs/stability, docs/performance). targets:",
    ]
    lines += [f"  {name:<{width}}  {desc}" for name, (_, desc) in CHART_TARGETS.items()]
    return "\n".join(lines)


def chart(rest: list[str]) -> int:
    """``skin-sim chart``: dispatch to a target; without one, list the targets and regenerate nothing."""
    if not rest or rest[0] in ("-h", "--help"):
        print(chart_usage())
        return 0 if rest else 2
    if rest[0] not in CHART_TARGETS:
        print(
            f"skin-sim chart: error: unknown target {rest[0]!r}{suggest(rest[0], CHART_TARGETS)}; "
            f"targets: {', '.join(CHART_TARGETS)}",
            file=sys.stderr,
        )
        return 2
    target, args = rest[0], rest[1:]
    docs = "--docs" in args
    args = [a for a in args if a != "--docs"]
    given = next(
        (
            a.split("=", 1)[1] if "=" in a else args[i + 1]
            for i, a in enumerate(args)
            if a == "--out" and i + 1 < len(args) or a.startswith("--out=")
        ),
        None,
    )
    if docs and given:
        print("skin-sim chart: error: --docs writes the tracked docs folder; give --docs or --out, not both", file=sys.stderr)
        return 2
    module = importlib.import_module(CHART_TARGETS[target][0])
    if docs:
        assert module.__file__ is not None  # a chart module is a file of skin_sim_lab
        out = Path(module.__file__).resolve().parents[2] / "docs" / CHART_DOCS[target]
        args += ["--out", str(out)]
    elif given:
        out = Path(given)
    else:
        out = CHART_OUT / target
        args += ["--out", str(out)]
    if "-h" in args or "--help" in args:
        return int(module.main(args) or 0)
    where = "the tracked docs (--docs)" if docs else "not the tracked docs (skin-sim chart TARGET --docs writes those)"
    print(f"skin-sim chart {target}: writing to {out}, {where}", flush=True)
    before = _files(out)
    code = int(module.main(args) or 0)
    written = sorted(p for p, m in _files(out).items() if before.get(p) != m)
    print(
        f"skin-sim chart {target}: wrote {len(written)} file(s) in {out}"
        + (": " + ", ".join(str(p.relative_to(out)) for p in written) if written else "")
    )
    return code


def _files(folder: Path) -> dict[Path, int]:
    """Files under ``folder`` with their modification times (ns)."""
    return {p: p.stat().st_mtime_ns for p in folder.rglob("*") if p.is_file()} if folder.is_dir() else {}


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
        print(
            f"skin-sim: error: unknown command {cmd!r}{suggest(cmd, [*COMMANDS, 'chart'])}; skin-sim --help lists the commands",
            file=sys.stderr,
        )
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
    except ConfigError as exc:  # a bad parameter (file, option) in an offline command: one line, exit 2
        print(f"skin-sim {cmd}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
