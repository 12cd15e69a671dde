"""``skin-sim demo``: the headless demo scene, end to end over real DDS.

Starts skin_sim_node, the device bridge and a simulated Touch (or the mock tool) as
separate processes, watches the node's outputs from this process, then prints what
happened (peak force, layers reached, achieved rate, latency percentiles) and writes a
picture of the deformation at peak force.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import time
from pathlib import Path

import numpy as np

from .model import load_tissue_config
from .scenes import DEFAULT_PARAMS, Scene


def summarize(monitor, wall_s: float) -> dict:
    f = monitor.forces()
    contact = list(monitor.contact)
    diags = [d for _, d, _, _ in monitor.diagnostics]
    out = {"wrenches": len(f), "wall_s": wall_s}
    out["peak_force_n"] = float(f[:, 2].max()) if len(f) else 0.0
    out["layers_reached"] = int(max((np.count_nonzero(c[3] > 0) for c in contact), default=0))
    rates = [float(d["achieved_rate_hz"]) for d in diags if d.get("input_stale") == "False"]
    out["achieved_rate_hz_median"] = float(np.median(rates)) if rates else float("nan")
    if len(f):
        lat_ms = (f[:, 0] - f[:, 1]) * 1e-6
        out["latency_ms_p50"], out["latency_ms_p99"], out["latency_ms_max"] = (
            float(np.percentile(lat_ms, 50)), float(np.percentile(lat_ms, 99)), float(lat_ms.max()),
        )  # fmt: skip
    kern = [float(d["kernel_us_p99"]) for d in diags if d.get("kernel_us_p99") not in (None, "nan")]
    out["kernel_us_p99_worst"] = max(kern) if kern else float("nan")
    return out


def _start_view(scene: Scene, out: Path):
    """``skin-sim view`` beside the scene; prints its URL. Without a display, it saves a screenshot of the page."""
    shot = ["--screenshot", str(out / "view.png"), "--shot-when-force-n", "0.02", "--shot-after-s", "0.5"]  # while pressing
    extra = [] if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY") else shot
    view = scene.start("view", "view", "--port", "0", *extra)
    scene.wait_for_log(view, "skin-sim view: http", timeout_s=60)
    url = view.log().split("skin-sim view: ", 1)[1].split()[0]
    print(f"  view: {url}" + (f" (screenshot: {out / 'view.png'})" if extra else ""), flush=True)
    return view if extra else None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim demo", description=__doc__.splitlines()[0])
    ap.add_argument("--source", choices=("device", "mock"), default="device", help="simulated Touch via the bridge, or mock tool")
    ap.add_argument("--path", default="press_all_layers", help="hand path / trajectory (see skin-sim mock-tool --list)")
    ap.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder for the picture and logs")
    ap.add_argument("--timeout-s", type=float, default=60.0)
    ap.add_argument(
        "--start-delay-s", type=float, default=2.5,
        help="tool source waits this long for DDS discovery before its path starts (up to 1.6 s measured)",
    )  # fmt: skip
    ap.add_argument("--view", action="store_true", help="also open the browser view (skin-sim view); headless: a screenshot")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    scene = Scene(args.out / "logs")
    os.environ["ROS_DOMAIN_ID"] = scene.env["ROS_DOMAIN_ID"]
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = scene.env["ROS_AUTOMATIC_DISCOVERY_RANGE"]
    from .perf.monitor import Monitor  # rclpy reads the domain at init

    cfg = load_tissue_config(DEFAULT_PARAMS)
    print(f"skin-sim demo: ROS_DOMAIN_ID={scene.env['ROS_DOMAIN_ID']}, source={args.source}, path={args.path}", flush=True)
    monitor = Monitor(record_depth=1)  # latency as a device sees it: newest sample
    ok = True
    try:
        node = scene.node()
        scene.wait_for_log(node, "live:", timeout_s=120)
        view = _start_view(scene, args.out) if args.view else None
        t0 = time.monotonic()
        if args.source == "device":
            scene.start("bridge", "bridge")
            source = scene.start("device", "device", "--hand-path", args.path, "--start-delay-s", str(args.start_delay_s))
        else:
            source = scene.start("mock_tool", "mock-tool", "--trajectory", args.path, "--start-delay-s", str(args.start_delay_s))
        try:
            source.popen.wait(timeout=args.timeout_s)
        except subprocess.TimeoutExpired:
            print(f"tool source did not finish within {args.timeout_s} s", flush=True)
            ok = False
        wall = time.monotonic() - t0
        time.sleep(1.2)  # one more diagnostics period
        if view is not None:  # headless view: let it finish its screenshot
            try:
                scene.wait_for_log(view, "screenshot", timeout_s=30)
            except (TimeoutError, RuntimeError) as exc:
                print(f"  view: no screenshot ({str(exc).splitlines()[0]})", flush=True)
    finally:
        codes = scene.stop_all()
        monitor.close()
    s = summarize(monitor, wall)
    ok &= all(c == 0 for c in codes.values()) and s["peak_force_n"] > 0
    print(f"  processes exited: {codes}")
    print(f"  wrenches received: {s['wrenches']} in {s['wall_s']:.1f} s")
    print(f"  peak force: {s['peak_force_n']:.4f} N; layers reached: {s['layers_reached']} of 3")
    print(f"  achieved haptic rate (node diagnostics, median of 1 s windows): {s['achieved_rate_hz_median']:.0f} Hz")
    if "latency_ms_p50" in s:
        print(
            f"  device pose -> force at observer latency: p50 {s['latency_ms_p50']:.2f} ms, "
            f"p99 {s['latency_ms_p99']:.2f} ms, max {s['latency_ms_max']:.2f} ms"
        )
    print(f"  model tick p99 (worst 1 s window): {s['kernel_us_p99_worst']:.1f} us")
    f = monitor.forces()
    if len(f) and monitor.layer_heights:
        t_peak = f[np.argmax(f[:, 2]), 0]
        rx = np.array([r for r, _, _ in monitor.layer_heights])
        img = monitor.layer_heights[int(np.argmin(np.abs(rx - t_peak)))][2]
        ny, nx = cfg.grid_shape
        sx, sy = cfg.sheet_size_m
        xs = -sx / 2 + (np.arange(nx) + 0.5) * sx / nx
        ys = -sy / 2 + (np.arange(ny) + 0.5) * sy / ny
        from .viz.plots import layer_heights_figure

        pic = layer_heights_figure(
            xs, ys, img, 0.0, args.out / "deformation_at_peak.png",
            f"demo {args.source}/{args.path}: deformation at peak force {s['peak_force_n']:.3f} N",
            bottom_m=cfg.total_thickness_m,
        )  # fmt: skip
        print(f"  picture: {pic}")
    else:
        ok = False
        print("  no deformation grid received")
    print("demo " + ("OK" if ok else "FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
