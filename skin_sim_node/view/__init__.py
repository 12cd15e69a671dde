"""``skin-sim view``: a live 3D view of the layered tissue in the browser, from the node's topics or a bag.

    skin-sim view                       # follow the live node (any namespace: --namespace /bed1)
    skin-sim view BAG [BAG ...]         # play recorded bags with a scrubbable timeline
    skin-sim view --bench               # node p99 latency with the view (and a headless page) open vs closed
    skin-sim view --compare-libs        # the library comparison of docs/view.md

Its own process: it never runs in the haptic node. See docs/view.md.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # main imports the one source it runs
    from .bag import BagSource
    from .live import LiveSource

DISPLAY_RATE_HZ = 30.0
"""Frames per second to the page: half a 60 Hz screen refresh; enough for a hand-speed press
(the node's grid comes at up to 60 Hz) and half the view's cost of 60. Measured in docs/view.md."""
_BROWSERS: list = []  # headless browsers this process opened (screenshots), closed on exit
PORT = 8642  # arbitrary unprivileged port; --port 0 picks a free one


def serve(source, host: str, port: int, duration_s: float | None = None, screenshot: Path | None = None, on_ready=None) -> int:
    """Run ``source`` behind a :class:`ViewServer` until interrupted (or ``duration_s``)."""
    from .server import ViewServer

    server = ViewServer(source, host, port).start()
    print(f"skin-sim view: {server.url}", flush=True)
    stop = threading.Event()

    def on_signal(*_):
        stop.set()
        source.stop()

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, on_signal)
        signal.signal(signal.SIGINT, on_signal)
    runner = threading.Thread(target=source.run, args=(server, duration_s), name="view-source", daemon=True)
    runner.start()
    if on_ready is not None:
        on_ready(server)
    try:
        runner.join()
    finally:
        for b in list(_BROWSERS):  # a screenshot still being taken: never leave a browser behind
            b.close()
        server.close()
        source.close()
    return 0


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    for flag, module in (("--bench", "bench"), ("--compare-libs", "libs")):
        if flag in argv:  # own argument sets: dispatch before this parser takes their options
            import importlib

            return int(importlib.import_module(f"{__name__}.{module}").main([a for a in argv if a != flag]) or 0)
    ap = argparse.ArgumentParser(prog="skin-sim view", description=__doc__.splitlines()[0])
    ap.add_argument("bags", nargs="*", type=Path, help="rosbag2 folders to play (none: follow the live node)")
    ap.add_argument("--namespace", default="", help="namespace of the node to follow (e.g. /bed1)")
    ap.add_argument("--host", default="127.0.0.1", help="address to serve on (127.0.0.1: this machine only)")
    ap.add_argument("--port", type=int, default=PORT, help="HTTP port (0: any free port)")
    ap.add_argument("--rate-hz", type=float, default=DISPLAY_RATE_HZ, help="frames per second sent to the page")
    ap.add_argument("--duration-s", type=float, help="stop after this long (default: until Ctrl-C)")
    ap.add_argument(
        "--contact",
        action="store_true",
        help="also read tissue/contact (per-layer stress, for the paper form's layer count); the node "
        "then publishes it every haptic tick, which costs its latency",
    )
    ap.add_argument(
        "--hands",
        help="the hands to follow, comma-separated namespaces (e.g. right,left; a leading comma: the first hand has the "
        "single-tool names) instead of the node's hand_ns / second_hand_ns parameters (the default)",
    )
    ap.add_argument(
        "--params",
        type=Path,
        help="a two-hand bag: the parameter file its hands' tools are drawn from (default: the shipped preset the bag "
        "names in skin_sim.params)",
    )
    ap.add_argument("--screenshot", type=Path, help="open the page in headless Chromium and save a PNG after --shot-after-s")
    ap.add_argument("--shot-after-s", type=float, default=3.0, help="delay before the screenshot")
    ap.add_argument(
        "--shot-when-force-n",
        type=float,
        default=0.0,
        help="take the screenshot once the shown force exceeds this (N; waits up to 60 s), then --shot-after-s",
    )
    ap.add_argument("--bench", action="store_true", help="latency benchmark: node p99 with the view open vs closed")
    ap.add_argument("--compare-libs", action="store_true", help="library comparison (mesh rate, CPU, install size)")
    args = ap.parse_args(argv)
    hint = None
    source: BagSource | LiveSource
    if args.bags:
        from msgs_schema.spec import ConfigError

        from ..bags.io import BagError
        from .bag import BagSource

        if args.params is not None and not args.params.is_file():
            print(f"skin-sim view: error: --params {args.params}: no such file", file=sys.stderr)
            return 2
        try:
            source = BagSource(args.bags, rate_hz=args.rate_hz, params=args.params)
        except (BagError, ConfigError) as exc:
            print(f"skin-sim view: error: {exc}", file=sys.stderr)
            return 2
        print(f"skin-sim view: {len(source.data.grids)} grid frames, {source.data.duration_s:.2f} s of bag", flush=True)
    else:
        from .live import LiveSource

        hands = tuple(n.strip() for n in args.hands.split(",")) if args.hands is not None else None
        if hands is not None:
            from msgs_schema.parameters import check_hands
            from msgs_schema.spec import ConfigError

            try:
                if len(hands) > 2:
                    raise ConfigError(f"--hands {args.hands}: at most 2 hands (the node's limit)")
                check_hands(hands[0], hands[1] if len(hands) > 1 else "")
            except ConfigError as exc:
                print(f"skin-sim view: error: {exc}", file=sys.stderr)
                return 2
        source = LiveSource(args.namespace, rate_hz=args.rate_hz, contact=args.contact, hands=hands)
        # a view started before its node serves at once, with default geometry, and says so (after its URL line)
        hint = None if source.refresh_geometry(wait_s=NODE_WAIT_S) else no_node_hint(source.namespace)
    shots: list[bool] = []

    def on_ready(server):
        if not args.bags and hint:
            print(hint, flush=True)
        if args.screenshot:

            def shoot():
                shots.append(_screenshot(server, args.screenshot, args.shot_after_s, args.shot_when_force_n))
                source.stop()  # the picture was what was asked for: the command ends after it

            threading.Thread(target=shoot, daemon=True).start()

    code = serve(source, args.host, args.port, args.duration_s, on_ready=on_ready)
    if args.screenshot and not all(shots or [False]):
        return 1  # asked for a picture and got none (the reason was printed), or stopped before it
    return code


NODE_WAIT_S = 3.0
"""How long the live view first waits for the node's parameter services: DDS discovery on one host took up to 1.6 s
here (docs/ros.md), so 3 s separates a slow discovery from no node."""


def no_node_hint(namespace: str) -> str:
    """The line the live view prints when no node answered: what it shows meanwhile and how to start one."""
    where = namespace if namespace not in ("", "/") else "/ (no namespace)"
    return (
        f"skin-sim view: no skin_sim_node answered in namespace {where} within {NODE_WAIT_S:g} s: the page shows an "
        "empty default tissue until one starts (skin-sim node, on this ROS_DOMAIN_ID; --namespace for another)"
    )


SHOT_GRID_DT_S = 0.05
"""A screenshot taken while pressing waits for a frame whose grid is at most this far in time from the tool's pose."""


def _screenshot(server, path: Path, after_s: float, when_force_n: float = 0.0) -> bool:
    """Open the page headless, save ``path`` (see the command's options), print what it shows; True when saved."""
    import time

    from .browser import Browser

    try:
        with Browser(server.url) as b:
            _BROWSERS.append(b)
            b.wait_for("window.skinView && window.skinView.gridFrames > 0", 30, "a tissue grid on the page")
            if when_force_n > 0:
                b.wait_for(f"window.skinView.force > {when_force_n}", 60, f"a force above {when_force_n} N")
            time.sleep(after_s)
            if when_force_n > 0:  # the picture shows the press it names: a grid within SHOT_GRID_DT_S of the tool, held
                b.hold_when(  # the page keeps that frame until the shot (it moved on before: a 0 N picture)
                    f"window.skinView.force > {when_force_n} && Math.abs(window.skinView.gridDtS) < {SHOT_GRID_DT_S}",
                    60,
                    f"a pressed frame whose grid is within {SHOT_GRID_DT_S * 1e3:.0f} ms of the tool",
                )
            n = b.evaluate("window.skinView.frames")
            b.wait_for(f"window.skinView.renderedFrames >= {n}", 30, "the frame rendered")
            dt = b.evaluate("window.skinView.gridDtS")
            f = b.evaluate("window.skinView.force")
            shot = b.screenshot(path)
            b.release()
            offset = f"grid {dt * 1e3:+.0f} ms from the tool" if isinstance(dt, (int, float)) else "no grid time offset known"
            print(f"skin-sim view: screenshot {shot} (force {f:.3f} N, {offset})", flush=True)
            return True
    except (OSError, RuntimeError, TimeoutError) as exc:
        print(f"skin-sim view: no screenshot: {exc}", flush=True)
        return False
