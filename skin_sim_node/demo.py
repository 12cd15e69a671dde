"""``skin-sim demo``: the headless demo scene, end to end over real DDS.

Starts skin_sim_node, the device bridge and a simulated Touch (or the mock tool) as
separate processes, watches the node's and the bridge's outputs from this process, then prints
what happened (peak force, layers reached, the node's tick rate, the device-side render rate and
its gaps, latency percentiles; each rate says what it counts) and writes a picture of the tissue at
the deepest instant, with the tool and a layer legend.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import time
from pathlib import Path

import numpy as np

from msgs_schema.tissue import LAYER_NAMES

from .model import load_tissue_config
from .scenes import DEFAULT_PARAMS, Scene

PROMISED_HZ = 1000.0
"""The rate the demo promises at the device: a Touch's 1 kHz servo loop (every device tick gets a force)."""

LAYER_COLOURS = ("#f2c9a5", "#d9777a", "#f5e08e")  # as skin_sim_node.viz.plots


def _median(values) -> float:
    return float(np.median(values)) if len(values) else float("nan")


def summarize(monitor, wall_s: float, poses: list) -> dict:
    f = monitor.forces()
    contact = list(monitor.contact)
    diags = [d for _, d, _, _ in monitor.diagnostics]
    node_d = [d for d in diags if "achieved_rate_hz" in d]
    bridge_d = [d for d in diags if "render_rate_hz" in d]
    out = {"wrenches": len(f), "wall_s": wall_s, "poses_seen": len(poses)}
    out["peak_force_n"] = float(f[:, 2].max()) if len(f) else 0.0
    out["layers_reached"] = int(max((np.count_nonzero(c[3] > 0) for c in contact), default=0))
    out["node_rate_hz"] = _median([float(d["achieved_rate_hz"]) for d in node_d if d.get("input_stale") == "False"])
    # windows in which the device ran throughout: the total grew since the window before and grows in the next
    tot = [int(d.get("rendered_total", 0)) for d in bridge_d]
    rates = [float(bridge_d[i]["render_rate_hz"]) for i in range(1, len(tot) - 1) if tot[i - 1] > 0 and tot[i + 1] > tot[i]]
    out["render_rate_hz_median"] = _median(rates)
    out["render_rate_hz_min"] = min(rates) if rates else float("nan")
    last = bridge_d[-1] if bridge_d else {}
    keys = ("rendered_total", "rendered_fresh_total", "rendered_no_model_total", "rendered_stale_model_total",
            "rendered_outside_radius_total", "device_gaps_2ms_total", "models_total")  # fmt: skip
    for key in keys:
        out[key] = int(last.get(key, 0))
    ages = [float(d["model_age_ms_max"]) for d in bridge_d if d.get("model_age_ms_max") not in (None, "nan")]
    out["model_age_ms_max"] = max(ages) if ages else float("nan")
    if len(f):
        lat_ms = (f[:, 0] - f[:, 1]) * 1e-6
        out["latency_ms_p50"], out["latency_ms_p99"], out["latency_ms_max"] = (
            float(np.percentile(lat_ms, 50)), float(np.percentile(lat_ms, 99)), float(lat_ms.max()),
        )  # fmt: skip
    kern = [float(d["kernel_us_p99"]) for d in node_d if d.get("kernel_us_p99") not in (None, "nan")]
    out["kernel_us_p99_worst"] = max(kern) if kern else float("nan")
    return out


def force_at_deepest(poses: list, wrenches: list, window_ns: int = 20_000_000):
    """``(depth_m, force_n)``: the wrench received nearest in time to the deepest tool pose, within ``window_ns``.

    ``poses`` are ``(rx_ns, x, y, z)`` and ``wrenches`` ``(rx_ns, stamp_ns, fz)`` as this process received them.
    """
    if not poses or not wrenches:
        return None
    t_deep, _, _, z = min(poses, key=lambda p: p[3])
    rx, _, fz = min(wrenches, key=lambda w: abs(w[0] - t_deep))
    return (-z, fz) if abs(rx - t_deep) <= window_ns else None


def deepest_figure(cfg, poses: list, layer_heights: list, path: Path, title: str) -> tuple[Path, float]:
    """Surface map and cross-section at the deepest tool instant, the tool drawn, a legend of the layers.

    ``poses``: (rx_ns, x, y, z) of ``tool/pose``; ``layer_heights``: the monitor's (rx_ns, stamp, image).
    Returns the path and the tool tip depth (m).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Patch, Rectangle

    p = np.array(poses, dtype=float)
    k = int(np.argmin(p[:, 3]))
    t_deep, tx, ty, tz = p[k]
    rx = np.array([r for r, _, _ in layer_heights], dtype=float)
    img = layer_heights[int(np.argmin(np.abs(rx - t_deep)))][2]
    ny, nx = cfg.grid_shape
    sx, sy = cfg.sheet_size_m
    xs = -sx / 2 + (np.arange(nx) + 0.5) * sx / nx
    ys = -sy / 2 + (np.arange(ny) + 0.5) * sy / ny
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(12, 4.6), gridspec_kw={"width_ratios": [1, 1.5]})
    ext = [xs[0] * 1e3, xs[-1] * 1e3, ys[0] * 1e3, ys[-1] * 1e3]
    im = a0.imshow(img[:, :, 0] * 1e3, origin="lower", extent=ext, cmap="viridis")
    plt.colorbar(im, ax=a0, label="surface height (mm)")
    r_mm = cfg.tool_radius_m * 1e3
    a0.add_patch(Circle((tx * 1e3, ty * 1e3), r_mm, fill=False, ec="w", lw=1.2, ls="--"))
    a0.set_xlabel("x (mm)")
    a0.set_ylabel("y (mm)")
    a0.set_title("surface height; dashed: tool footprint", fontsize=9)
    row = int(np.argmin(np.abs(ys - ty)))
    tops = [img[row, :, i] for i in range(img.shape[2])]
    bottom = np.full_like(xs, -cfg.total_thickness_m)
    handles = []
    for i, (top, below) in enumerate(zip(tops, tops[1:] + [bottom])):
        a1.fill_between(xs * 1e3, below * 1e3, top * 1e3, color=LAYER_COLOURS[i % 3], lw=0)
        a1.plot(xs * 1e3, top * 1e3, "k", lw=0.5)
        handles.append(Patch(color=LAYER_COLOURS[i % 3], label=LAYER_NAMES[i] if i < 3 else f"layer {i}"))
    if cfg.tool_shape == "sphere":
        a1.add_patch(Circle((tx * 1e3, tz * 1e3 + r_mm), r_mm, color="0.35", alpha=0.85, zorder=5))
    else:  # flat punch: a cylinder of the tool radius, drawn 3 radii tall
        a1.add_patch(Rectangle((tx * 1e3 - r_mm, tz * 1e3), 2 * r_mm, 3 * r_mm, color="0.35", alpha=0.85, zorder=5))
    handles.append(Patch(color="0.35", label=f"{cfg.tool_shape} tool (r = {r_mm:.1f} mm), tip at z = {tz * 1e3:.2f} mm"))
    half = max(4 * r_mm, 6.0)
    a1.set_xlim(tx * 1e3 - half, tx * 1e3 + half)
    a1.set_ylim(-cfg.total_thickness_m * 1e3, max(2 * r_mm + 0.5, 1.0))
    a1.set_aspect("equal")
    a1.set_xlabel("x (mm)")
    a1.set_ylabel("z (mm)")
    a1.set_title(f"cross-section at y = {ys[row] * 1e3:.1f} mm, grid image nearest the deepest instant", fontsize=9)
    a1.legend(handles=handles, fontsize=8, loc="upper right")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path, -tz


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
    from msgs_schema import convert as cv
    from msgs_schema.qos import subscription

    from .perf.monitor import Monitor  # rclpy reads the domain at init

    cfg = load_tissue_config(DEFAULT_PARAMS)
    print(f"skin-sim demo: ROS_DOMAIN_ID={scene.env['ROS_DOMAIN_ID']}, source={args.source}, path={args.path}", flush=True)
    monitor = Monitor(record_depth=1)  # latency as a device sees it: newest sample
    poses: list = []
    subscription(monitor.node, "tool_pose", lambda m: poses.append((monitor.now_ns(), *cv.read_pose(m)[2])))
    ok = True
    procs = {}
    try:
        node = scene.node()
        scene.wait_for_log(node, "live:", timeout_s=120)
        view = _start_view(scene, args.out) if args.view else None
        t0 = time.monotonic()
        if args.source == "device":
            procs["bridge"] = scene.start("bridge", "bridge")
            source = scene.start("device", "device", "--hand-path", args.path, "--start-delay-s", str(args.start_delay_s))
            procs["device"] = source
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
    s = summarize(monitor, wall, poses)
    ok &= all(c == 0 for c in codes.values()) and s["peak_force_n"] > 0
    print(f"  processes exited: {codes}")
    print(f"  peak force: {s['peak_force_n']:.4f} N; layers reached: {s['layers_reached']} of 3")
    deep = force_at_deepest(poses, monitor.wrench)
    if deep is not None:
        depth_m, force_n = deep
        verdict = "the run's maximum" if force_n >= 0.99 * s["peak_force_n"] else "NOT the run's maximum"
        print(f"  force at the deepest point ({depth_m * 1e3:.2f} mm): {force_n:.4f} N, {verdict} (1 % tolerance)")
    else:
        print("  force at the deepest point: no tool/wrench received within 20 ms of the deepest pose at this observer")
    print(
        f"  node: {s['node_rate_hz']:.0f} haptic ticks/s (node diagnostics achieved_rate_hz: model ticks per second, "
        "median of its 1 s windows with the tool present)"
    )
    print(
        f"  observer: {s['wrenches']} tool/wrench messages received in {s['wall_s']:.1f} s of scene "
        f"({s['wrenches'] / max(s['wall_s'], 1e-9):.0f} /s; a depth-1 reader in this process, so it may miss some)"
    )
    if args.source == "device":
        dev_ticks = re.search(r"sim device stopping: (\d+) ticks, (\d+) overruns", procs["device"].log())
        print(
            f"  device render: {s['render_rate_hz_median']:.0f} forces/s commanded to the device (bridge diagnostics "
            f"render_rate_hz: device ticks rendered per second, median of 1 s windows; lowest {s['render_rate_hz_min']:.0f})"
        )
        print(
            f"  device ticks: {s['rendered_total']} rendered by the bridge, {s['rendered_fresh_total']} from a contact model "
            f"valid at that pose, {s['rendered_stale_model_total']} with the model older than its TTL and "
            f"{s['rendered_outside_radius_total']} outside its radius (fading) after the first model, "
            f"{s['rendered_total'] - s['rendered_fresh_total'] - s['rendered_no_model_total']} before it (lifted, discovery); "
            f"oldest model used {s['model_age_ms_max']:.1f} ms; {s['device_gaps_2ms_total']} device pose gaps > 2 ms at the "
            f"bridge; {s['models_total']} contact models received"
            + (f"; the simulated device ran {dev_ticks.group(1)} ticks ({dev_ticks.group(2)} overruns)" if dev_ticks else "")
        )
        if not s["render_rate_hz_median"] >= 0.95 * PROMISED_HZ:
            ncpu = os.cpu_count() or 1
            print(
                f"  below the promised {PROMISED_HZ:.0f} forces/s: the device's poses (its servo ticks) did not all reach the "
                f"bridge in time; load average {os.getloadavg()[0]:.1f} on {ncpu} CPUs (the processes share them)"
            )
    if "latency_ms_p50" in s:
        print(
            f"  device pose -> tool/wrench at this observer: p50 {s['latency_ms_p50']:.2f} ms, "
            f"p99 {s['latency_ms_p99']:.2f} ms, max {s['latency_ms_max']:.2f} ms"
        )
    print(f"  model tick p99 (worst 1 s window of the node): {s['kernel_us_p99_worst']:.1f} us")
    if poses and monitor.layer_heights:
        pic, depth = deepest_figure(
            cfg, poses, monitor.layer_heights, args.out / "deformation_deepest.png",
            f"demo {args.source}/{args.path}: tissue at the deepest tool instant ({s['layers_reached']} of 3 layers reached "
            f"during the run, peak force {s['peak_force_n']:.3f} N)",
        )  # fmt: skip
        print(f"  picture (deepest instant, tool tip {depth * 1e3:.2f} mm below the rest surface): {pic}")
    else:
        ok = False
        print("  no deformation grid or tool pose received")
    print("demo " + ("OK" if ok else "FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
