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
from typing import Any

import numpy as np

from ..scenes import DEFAULT_PARAMS, Scene
from ..verdicts import exit_code, verdict_line

PROMISED_HZ = 1000.0
"""The rate the demo promises at the device: a Touch's 1 kHz servo loop (every device tick gets a force)."""
RATE_TOLERANCE = 0.05
"""The rate check's tolerance: a measured rate at least 95 % of :data:`PROMISED_HZ` holds it. The rates are medians of
1 s diagnostics windows, so 5 % is 50 missed ticks a second: more than a shared machine's jitter gives a loop that
keeps up (a few late wake-ups a second), less than a loop that falls behind loses (whole tens of ms at a time)."""
FIFO_PRIORITY_NEEDED = 1
"""The least ``RLIMIT_RTPRIO`` that lets an unprivileged user run a thread under SCHED_FIFO (``rt_priority``)."""


def layers_reached(depth_m: float, cfg) -> list[str]:
    """The layers whose rest top lies above the tip: reached from the tool's depth, not from the chain.

    Parameters
    ----------
    depth_m : float
        The tip's depth below the rest surface (m); <= 0: not touching.
    cfg : TissueConfig

    Returns
    -------
    list of str
        Layer names, top down (the epidermis from any depth > 0; the dermis once the tip is below the epidermis'
        mean rest thickness, and so on).
    """
    out, top_m = [], 0.0
    for layer in cfg.layers:
        if depth_m > top_m:
            out.append(layer.name)
        top_m += layer.thickness_m
    return out


def rate_check(what: str, measured_hz: float, target_hz: float = PROMISED_HZ, tolerance: float = RATE_TOLERANCE):
    """``(held, text)``: whether ``measured_hz`` holds ``target_hz`` within ``tolerance`` (a fraction), and the figures."""
    held = bool(measured_hz >= (1.0 - tolerance) * target_hz)  # NaN (nothing measured) is not held
    return held, f"{what} {measured_hz:.0f}/s of {target_hz:.0f}/s (tolerance {tolerance * 100:.0f} %)"


def rate_reasons(n_processes: int, overruns: int | None = None) -> str:
    """Why a machine may not hold the rate, from what this process can see: CPU load and count, and scheduling.

    Parameters
    ----------
    n_processes : int
        Processes of the scene that each run a 1 kHz loop.
    overruns : int, optional
        The simulated device's own late ticks (its servo loop woke more than a period late).

    Returns
    -------
    str
    """
    import resource

    ncpu = os.cpu_count() or 1
    load = os.getloadavg()[0]
    cpu = f"CPU: load average {load:.1f} on {ncpu} CPUs, {n_processes} processes of this scene each running a 1 kHz loop"
    if overruns:
        cpu += f", the simulated device woke late {overruns} times"
    soft = resource.getrlimit(resource.RLIMIT_RTPRIO)[0]
    can_fifo = os.geteuid() == 0 or soft == resource.RLIM_INFINITY or soft >= FIFO_PRIORITY_NEEDED
    prio = (
        "priorities: SCHED_FIFO allowed here (the node's haptic threads at rt_priority 50, the bridge's servo thread at "
        "80, the defaults; the simulated device at normal priority)"
        if can_fifo
        else "priorities: SCHED_FIFO not allowed (not root, RLIMIT_RTPRIO 0): every process at normal scheduling"
    )
    return f"{cpu}; {prio}"


def _median(values) -> float:
    return float(np.median(values)) if len(values) else float("nan")


def summarize(monitor, wall_s: float, poses: list) -> dict:
    f = monitor.forces()
    contact = list(monitor.contact)
    diags = [d for _, d, _, _ in monitor.diagnostics]
    node_d = [d for d in diags if "achieved_rate_hz" in d]
    bridge_d = [d for d in diags if "render_rate_hz" in d]
    out: dict[str, Any] = {"wrenches": len(f), "wall_s": wall_s, "poses_seen": len(poses)}
    out["peak_force_n"] = float(f[:, 2].max()) if len(f) else 0.0
    out["layers_reached"] = int(max((np.count_nonzero(c[3] > 0) for c in contact), default=0))
    live = [d for d in node_d if d.get("input_stale") == "False"]
    out["node_rate_hz"] = _median([float(d["achieved_rate_hz"]) for d in live])
    # the rate the node answers at in those windows (its server rate follows the machine: skin_sim_node/rate.py)
    served = [float(d.get("server_rate_hz", d.get("target_rate_hz", "nan"))) for d in live]
    out["server_rate_hz"] = _median(served)
    # each window against the rate announced in it (the governor may change it between windows): the median share
    out["node_rate_share"] = _median([float(d["achieved_rate_hz"]) / r for d, r in zip(live, served) if r > 0])
    steps = {d.get("rate_reason", "target") for d in node_d}
    out["rate_reasons"] = sorted(steps - {"target", "rate_hz"})
    # windows in which the device ran throughout: the total grew since the window before and grows in the next
    tot = [int(d.get("rendered_total", 0)) for d in bridge_d]
    rates = [float(bridge_d[i]["render_rate_hz"]) for i in range(1, len(tot) - 1) if tot[i - 1] > 0 and tot[i + 1] > tot[i]]
    out["render_rate_hz_median"] = _median(rates)
    out["render_rate_hz_min"] = min(rates) if rates else float("nan")
    last = bridge_d[-1] if bridge_d else {}
    keys = (
        "rendered_total",
        "rendered_fresh_total",
        "rendered_no_model_total",
        "rendered_stale_model_total",
        "rendered_outside_radius_total",
        "device_gaps_2ms_total",
        "models_total",
    )
    for key in keys:
        out[key] = int(last.get(key, 0))
    ages = [float(d["model_age_ms_max"]) for d in bridge_d if d.get("model_age_ms_max") not in (None, "nan")]
    out["model_age_ms_max"] = max(ages) if ages else float("nan")
    if len(f):
        lat_ms = (f[:, 0] - f[:, 1]) * 1e-6
        out["latency_ms_p50"], out["latency_ms_p99"], out["latency_ms_max"] = (
            float(np.percentile(lat_ms, 50)),
            float(np.percentile(lat_ms, 99)),
            float(lat_ms.max()),
        )
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


def model_at(inputs, params, stamp_ns: int):
    """The tissue model after the offline session has answered every pose of ``inputs`` up to ``stamp_ns``.

    Returns ``(model, (x, y, z), n_affected)``: the whole dynamic state copied from the session at that tick.
    """
    from ..bags.inputs import POSE
    from ..bags.offline import load_params
    from ..model import SkinModel
    from ..session import HapticSession
    from ..tools import make_tool

    sp, cfg = load_params(params)
    session = HapticSession(make_tool(cfg), sp)
    prev, last = None, None
    for stamp, rank, frame, xyz, quat in inputs.events:
        if stamp > stamp_ns:
            break
        if rank != POSE:
            session.on_twist(stamp, frame, xyz)
        elif session.on_pose(stamp, frame, xyz, quat=quat) is None:
            last = session.tick(stamp, 0 if prev is None else stamp - prev)
            prev = stamp
    model = SkinModel(cfg)
    model.set_state(session.state())
    return model, tuple(last.x0_m) if last is not None else (0.0, 0.0, 1.0), last.n_affected if last is not None else 0


def deepest_figure(model, tool_xyz, path: Path, title: str, note: str) -> Path:
    """Surface map and cross-section of ``model`` (the state at the deepest pose), the tool drawn at ``tool_xyz``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..bags.plots import cross_section_legend, draw_cross_section, draw_surface, save_figure

    x, y, z = tool_xyz
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(12, 4.8), gridspec_kw={"width_ratios": [1, 1.5]})
    draw_surface(a0, model, "surface height at that instant", tool_xy=(x, y))
    half = max(4 * model.cfg.tool_radius_m, 8e-3)
    draw_cross_section(a1, model, x, y, z, f"cross-section at y = {y * 1e3:.1f} mm, same instant", half_m=half)
    cross_section_legend(a1)
    fig.text(0.5, 0.01, note, ha="center", fontsize=8)
    fig.subplots_adjust(bottom=0.14)
    return save_figure(fig, path, title, rect=(0, 0.05, 1, 1))


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
        "--start-delay-s",
        type=float,
        default=2.5,
        help="tool source waits this long for DDS discovery before its path starts (up to 1.6 s measured)",
    )
    ap.add_argument("--view", action="store_true", help="also open the browser view (skin-sim view); headless: a screenshot")
    ap.add_argument(
        "--hands",
        type=int,
        choices=(1, 2),
        default=1,
        help="2: the two-hand scene (a needle and an anchoring finger, config/two_hands.yaml; issue 32)",
    )
    args = ap.parse_args(argv)
    if args.hands == 2:
        from .hands import main as two_hands

        if args.out == Path("out/demo"):
            args.out = Path("out/demo_hands")
        return two_hands(args)
    args.out.mkdir(parents=True, exist_ok=True)
    scene = Scene(args.out / "logs")
    os.environ["ROS_DOMAIN_ID"] = scene.env["ROS_DOMAIN_ID"]
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = scene.env["ROS_AUTOMATIC_DISCOVERY_RANGE"]
    from msgs_schema import convert as cv
    from msgs_schema.qos import subscription

    from ..bags.monitor import Monitor  # rclpy reads the domain at init

    print(f"skin-sim demo: ROS_DOMAIN_ID={scene.env['ROS_DOMAIN_ID']}, source={args.source}, path={args.path}", flush=True)
    monitor = Monitor(record_depth=1)  # latency as a device sees it: newest sample
    poses: list = []
    subscription(monitor.node, "tool_pose", lambda m: poses.append((monitor.now_ns(), *cv.read_pose(m)[2])))
    from ..bags.recorder import Recorder

    # every input and published force (deep queues), for the offline check and out/demo/bag
    rec = Recorder(RECORDED, None, name="skin_sim_demo_recorder", keep=True, executor="events")
    checks: list = []
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
            checks.append((True, "tool path finished"))
        except subprocess.TimeoutExpired:
            checks.append((False, f"tool path did not finish within {args.timeout_s:g} s"))
        wall = time.monotonic() - t0
        time.sleep(1.2)  # one more diagnostics period
        if view is not None:  # headless view: let it finish its screenshot
            try:
                scene.wait_for_log(view, "screenshot", timeout_s=30)
                checks.append((True, f"view screenshot {args.out / 'view.png'}"))
            except (TimeoutError, RuntimeError) as exc:
                print(f"  view: no screenshot ({str(exc).splitlines()[0]})", flush=True)
                checks.append((False, "view screenshot not written"))
    finally:
        codes = scene.stop_all()
        monitor.close()
        rec.close()
    s = summarize(monitor, wall, poses)
    bad = {k: c for k, c in codes.items() if c != 0}
    checks.append((not bad, "processes exited 0" if not bad else f"processes exited non-zero: {bad}"))
    checks.append((s["peak_force_n"] > 0, f"peak force {s['peak_force_n']:.4f} N > 0"))
    print(f"  processes exited: {codes}")
    from ..model.config import load_tissue_config

    cfg = load_tissue_config(DEFAULT_PARAMS)
    depth_m = max((-p[3] for p in poses), default=0.0)
    reached = layers_reached(depth_m, cfg)
    tops = ", ".join(f"{cfg.layers[i].name} {sum(la.thickness_m for la in cfg.layers[:i]) * 1e3:.3f} mm" for i in range(1, 3))
    print(
        f"  layers reached: {len(reached)} of {len(cfg.layers)} ({', '.join(reached) or 'none'}): the tip's deepest pose "
        f"{depth_m * 1e3:.3f} mm below the rest surface against the rest tops ({tops})"
    )
    print(f"  peak force at this observer: {s['peak_force_n']:.4f} N (a depth-1 reader; the recorded peak is below)")
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
    dev_ticks = None
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
    if "latency_ms_p50" in s:
        print(
            f"  device pose -> tool/wrench at this observer: p50 {s['latency_ms_p50']:.2f} ms, "
            f"p99 {s['latency_ms_p99']:.2f} ms, max {s['latency_ms_max']:.2f} ms"
        )
    print(f"  model tick p99 (worst 1 s window of the node): {s['kernel_us_p99_worst']:.1f} us")
    print(
        f"  server rate: {s['server_rate_hz']:.0f} Hz (node diagnostics server_rate_hz, median of the same windows; the "
        "node steps down from 1000 Hz when the machine does not hold it and the bridge renders its model in between)"
        + (f"; why: {'; '.join(s['rate_reasons'])}" if s["rate_reasons"] else "")
    )
    # the promise at the device is 1 kHz; the node's promise is to answer at the server rate it announces
    share = s["node_rate_share"]
    held = bool(share >= 1.0 - RATE_TOLERANCE)  # NaN (nothing measured) is not held
    rates = [
        (
            held,
            f"node ticks {100 * share:.0f} % of the server rate each 1 s window announced (median; tolerance "
            f"{RATE_TOLERANCE * 100:.0f} %; {s['node_rate_hz']:.0f}/s at a median {s['server_rate_hz']:.0f} Hz)",
        )
    ]
    if args.source == "device":
        rates.append(rate_check("device forces", s["render_rate_hz_median"]))
    if all(ok for ok, _ in rates):
        checks.append((True, "rate held: " + ", ".join(t for _, t in rates)))
    else:
        overruns = int(dev_ticks.group(2)) if dev_ticks else None
        why = rate_reasons(4 if args.source == "device" else 3, overruns)
        checks.append((False, "rate NOT held: " + ", ".join(t for _, t in rates) + f"; {why}"))
    print("  rate: " + ("held" if checks[-1][0] else "NOT held") + ": " + checks[-1][1].split(": ", 1)[1])
    checks += offline_check(rec.records, args, s)
    print(verdict_line("demo", checks))
    return exit_code(checks)


RECORDED = ("tool_pose", "tool_twist", "tool_wrench")


def offline_check(records: list, args, s: dict) -> list:
    """Write ``OUT/bag``, replay the poses the node answered offline, check the published forces, draw the picture.

    Returns the checks: the published forces are the offline answer; the picture was written.
    """
    from msgs_schema.topics import TOPICS

    from ..bags.compare import read_outputs
    from ..bags.inputs import InputOptions, read_inputs
    from ..bags.io import BagError, BagWriter, qos_profiles
    from ..bags.offline import bag_topic, replay
    from ..bags.published import answered_only, check_published, format_check

    bag = args.out / "bag"
    with BagWriter(
        bag, "mcap", custom_data={"skin_sim.scene": f"demo-{args.source}", "skin_sim.path": args.path}, overwrite=True
    ) as w:
        for key in RECORDED:
            w.add_topic(bag_topic(key), TOPICS[key].type, qos_profiles(key))
        for rx, key, raw in records:
            w.write_raw(bag_topic(key), TOPICS[key].type, rx, raw)
    try:
        inputs = read_inputs(bag, InputOptions())
        published, _ = read_outputs(bag, grids=False)
    except BagError as exc:
        return [(False, f"no offline check: {exc}")]
    inputs = answered_only(inputs, set(published))
    res = replay(inputs, DEFAULT_PARAMS, None, 0.0)
    if res.stamps_ns.size == 0:
        return [(False, "no published force answers a recorded pose: nothing to check offline")]
    c = check_published(res.forces_by_stamp(), published)
    print("  " + format_check(c, "published forces vs offline replay of the same poses", int(res.stamps_ns[0])))
    peak_pub = max((float(np.linalg.norm(f)) for f in published.values()), default=0.0)
    print(
        f"  peak force: {peak_pub:.4f} N published (every recorded tool/wrench), {res.peak_force_n:.4f} N offline for the "
        f"same {res.stamps_ns.size} poses"
    )
    print(f"  recorded to {bag} (skin-sim replay {bag} replays it)")
    checks = [
        (
            c.ok,
            "published forces are the offline answer"
            if c.ok
            else "published forces DISAGREE with the "
            f"offline answer (max |dF| {c.diff.max_df_n:.3g} N at {c.diff.matched} matched stamps)",
        )
    ]
    k = int(np.argmin(res.tool_xyz_m[:, 2]))
    stamp = int(res.stamps_ns[k])
    model, xyz, n_aff = model_at(inputs, DEFAULT_PARAMS, stamp)
    pub = published.get(stamp)
    pic = deepest_figure(
        model,
        xyz,
        args.out / "deformation_deepest.png",
        f"demo {args.source}/{args.path}: the tissue at the deepest pose, t = {(stamp - res.stamps_ns[0]) * 1e-9:.3f} s, "
        f"tip {-xyz[2] * 1e3:.2f} mm deep, force {res.force_n[k]:.3f} N (run's peak {res.peak_force_n:.3f} N)",
        "model state of the offline replay at that pose's stamp (time offset to the tool: 0 ms); the node published "
        + (f"{np.linalg.norm(pub):.4f} N for it" if pub is not None else "no wrench for it")
        + f"; {n_aff} of 3 layers under the tool",
    )
    print(f"  picture: {pic} (the deepest pose, tip {-xyz[2] * 1e3:.2f} mm below the rest surface; model state at its stamp)")
    return checks + [(True, f"picture {pic}")]


if __name__ == "__main__":
    raise SystemExit(main())
