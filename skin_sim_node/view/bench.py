"""``skin-sim view --bench``: what the view costs the haptic loop, measured in one run.

One node and one mock tool (looping ``press_all_layers``) run throughout. Phases alternate:
view closed; the ``skin-sim view`` process alone (subscribed, no page); view open (the process plus
a headless Chromium showing the page), ``--cycles`` times. An observer (``bags.monitor.StreamObserver``, newest sample only, as
a device sees it) takes pose-to-force latency from each wrench: its stamp is the stamp of the pose
it answers (input loop mode), so ``arrival - stamp`` is the pose-to-force latency at a device.
Printed: per phase and pooled, median and p99 latency, the node's missed slots and rate (its
diagnostics), the view's and the browser's CPU, the page's frame and grid rates, and the ratios
open / closed. The machine's other load shows in both phases alike; only the ratios are compared.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
import psutil
from tqdm import tqdm

from ..scenes import Scene


def _cpu_s(pids: list[int]) -> float:
    total = 0.0
    for pid in pids:
        try:
            t = psutil.Process(pid).cpu_times()
            total += t.user + t.system
        except psutil.NoSuchProcess:
            pass
    return total


def _latency(records, t_from_ns: int) -> np.ndarray:
    """Pose-to-force latencies (ms) of the wrenches that answer a pose (stamp within 0.1 s of arrival)."""
    lat = np.array([(rx - st) * 1e-6 for rx, st, _ in records if rx >= t_from_ns], dtype=float)
    return lat[(lat >= 0) & (lat < 100)]


def run(duration_s: float, cycles: int, out: Path, rate_hz: float) -> dict:
    from ..bags.monitor import StreamObserver
    from .browser import Browser

    phases = []
    with Scene(out / "logs") as scene:
        os.environ["ROS_DOMAIN_ID"] = scene.env["ROS_DOMAIN_ID"]
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = scene.env["ROS_AUTOMATIC_DISCOVERY_RANGE"]
        print(
            f"skin-sim view --bench: ROS_DOMAIN_ID={scene.env['ROS_DOMAIN_ID']}, {cycles} x (closed, view alone, view + page) "
            f"of {duration_s:.0f} s",
            flush=True,
        )
        node = scene.node()
        scene.wait_for_log(node, "live:", timeout_s=180)
        mon = StreamObserver("view_bench_observer", record_depth=1)
        scene.start("mock_tool", "mock-tool", "--trajectory", "press_all_layers", "--loop", "--start-delay-s", "1")
        mon.wait_for(lambda: len(mon.wrench) > 100, 60, "wrenches from the node")
        time.sleep(2.0)  # past the first press's start
        node_pid = node.popen.pid
        bar = tqdm(total=3 * cycles, desc="phases", unit="phase")
        for k in range(cycles):
            for kind in ("closed", "view", "open"):
                view = browser = None
                extra = {}
                if kind != "closed":
                    view = scene.start(f"view_{k}", "view", "--port", "0", "--rate-hz", str(rate_hz))
                    scene.wait_for_log(view, "skin-sim view: http", timeout_s=60)
                    url = view.log().split("skin-sim view: ", 1)[1].split()[0]
                    if kind == "open":
                        browser = Browser(url)
                        browser.wait_for("window.skinView && window.skinView.gridFrames > 0", 60, "a grid on the page")
                    time.sleep(1.0)
                    if browser is not None:
                        f0 = browser.evaluate("[window.skinView.frames, window.skinView.gridFrames]")
                vpid = [view.popen.pid] if view else []
                pids = vpid + (browser.pids if browser else [])
                c0, v0, n0, t0 = _cpu_s(pids), _cpu_s(vpid), _cpu_s([node_pid]), time.monotonic()
                t_from = mon.now_ns()
                mon.diagnostics.clear()
                time.sleep(duration_s)
                wall = time.monotonic() - t0
                cpu, view_cpu, node_cpu = _cpu_s(pids) - c0, _cpu_s(vpid) - v0, _cpu_s([node_pid]) - n0
                lat = _latency(list(mon.wrench), t_from)
                diags = [d for _, d, _, _ in mon.diagnostics]
                if browser is not None:
                    f1 = browser.evaluate("[window.skinView.frames, window.skinView.gridFrames]")
                    extra = {"page_frames_hz": (f1[0] - f0[0]) / wall, "page_grids_hz": (f1[1] - f0[1]) / wall}
                    browser.close()
                if view is not None:
                    scene.stop(view)
                phases.append(
                    {
                        "view": kind,
                        "view_cpu_pct": 100 * view_cpu / wall,
                        "cycle": k,
                        "n": int(lat.size),
                        "latency_ms": lat.tolist(),
                        "p50_ms": float(np.percentile(lat, 50)) if lat.size else float("nan"),
                        "p99_ms": float(np.percentile(lat, 99)) if lat.size else float("nan"),
                        "missed_slots": int(sum(int(d.get("missed_slots_window", 0)) for d in diags)),
                        "rate_hz": float(np.median([float(d["achieved_rate_hz"]) for d in diags])) if diags else float("nan"),
                        "view_browser_cpu_pct": 100 * cpu / wall,
                        "node_cpu_pct": 100 * node_cpu / wall,
                        **extra,
                    }
                )
                bar.update(1)
        bar.close()
        mon.close()
    return {"phases": phases, "duration_s": duration_s, "rate_hz": rate_hz, "cpus": os.cpu_count()}


def summarize(res: dict) -> dict:
    out: dict[str, Any] = {}
    for kind in ("closed", "view", "open"):
        ph = [p for p in res["phases"] if p["view"] == kind]
        lat = np.concatenate([np.array(p["latency_ms"]) for p in ph]) if ph else np.zeros(0)
        out[kind] = {
            "n": int(lat.size),
            "p50_ms": float(np.percentile(lat, 50)) if lat.size else float("nan"),
            "p99_ms": float(np.percentile(lat, 99)) if lat.size else float("nan"),
            "missed_slots_per_s": sum(p["missed_slots"] for p in ph) / (len(ph) * res["duration_s"]) if ph else float("nan"),
            "node_cpu_pct": float(np.mean([p["node_cpu_pct"] for p in ph])) if ph else float("nan"),
            "view_browser_cpu_pct": float(np.mean([p["view_browser_cpu_pct"] for p in ph])) if ph else float("nan"),
            "view_cpu_pct": float(np.mean([p["view_cpu_pct"] for p in ph])) if ph else float("nan"),
        }
    opened = [p for p in res["phases"] if p["view"] == "open"]
    out["page_frames_hz"] = float(np.mean([p["page_frames_hz"] for p in opened])) if opened else float("nan")
    out["page_grids_hz"] = float(np.mean([p["page_grids_hz"] for p in opened])) if opened else float("nan")
    c, v, o = out["closed"], out["view"], out["open"]
    out["ratio_p50"] = o["p50_ms"] / c["p50_ms"]
    out["ratio_p99"] = o["p99_ms"] / c["p99_ms"]
    out["ratio_p99_view_only"] = v["p99_ms"] / c["p99_ms"]
    return out


def print_summary(res: dict, s: dict) -> None:
    print(
        f"\nview closed vs open, same node process, {len(res['phases'])} alternating phases of {res['duration_s']:.0f} s "
        f"(machine shared: compare the ratios)"
    )
    for p in res["phases"]:
        print(
            f"  cycle {p['cycle']} view {p['view']:6s}: latency p50 {p['p50_ms']:.3f} ms p99 {p['p99_ms']:.3f} ms "
            f"(n {p['n']}), node rate {p['rate_hz']:.0f} Hz, missed slots {p['missed_slots']}, "
            f"node CPU {p['node_cpu_pct']:.0f} %, view CPU {p['view_cpu_pct']:.0f} %, "
            f"view+browser CPU {p['view_browser_cpu_pct']:.0f} %"
            + (f", page {p['page_frames_hz']:.1f} frames/s, {p['page_grids_hz']:.1f} grids/s" if "page_frames_hz" in p else "")
        )
    for kind in ("closed", "view", "open"):
        c = s[kind]
        print(
            f"pooled {kind:6s}: p50 {c['p50_ms']:.3f} ms, p99 {c['p99_ms']:.3f} ms, "
            f"missed slots {c['missed_slots_per_s']:.1f}/s, "
            f"view CPU {c['view_cpu_pct']:.0f} %, view+browser CPU {c['view_browser_cpu_pct']:.0f} % of one core"
        )
    print(
        f"ratio to closed: view process alone p99 {s['ratio_p99_view_only']:.2f}; view + page p50 {s['ratio_p50']:.2f}, "
        f"p99 {s['ratio_p99']:.2f}; page {s['page_frames_hz']:.1f} frames/s, {s['page_grids_hz']:.1f} grid updates/s"
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim view --bench", description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=10.0, help="measured seconds per phase")
    ap.add_argument("--cycles", type=int, default=2, help="closed/open pairs")
    ap.add_argument("--rate-hz", type=float, default=30.0, help="view frame rate")
    ap.add_argument("--out", type=Path, default=Path("out/view_bench"))
    args = ap.parse_args(argv)
    from .browser import find_browser

    if find_browser() is None:
        print("skin-sim view --bench: needs Chromium (apt-get install chromium)")
        return 2
    res = run(args.duration_s, args.cycles, args.out, args.rate_hz)
    s = summarize(res)
    print_summary(res, s)
    args.out.mkdir(parents=True, exist_ok=True)
    for p in res["phases"]:
        p.pop("latency_ms")
    (args.out / "bench.json").write_text(json.dumps({"summary": s, **res}, indent=1))
    print(f"written {args.out / 'bench.json'}")
    return 0
