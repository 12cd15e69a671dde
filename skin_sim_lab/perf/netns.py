"""``skin-sim netns-role``: the Python side of ``scripts/netns_scale.sh`` (DDS across network namespaces).

``device``: run in the device-side namespace: starts the device bridge and a simulated Touch
looping the ``press_hold_release`` hand path, observes ``tool/wrench`` with reader depth 1 and
measures the loop latency = wrench arrival here - the stamp of the device pose it answers
(the node, in ``input`` mode, stamps each wrench with its pose's stamp; the bridge keeps the
device's stamp). Every clock is the same host clock, so no offset enters. Writes a JSON row.

``compare``: prints the rows of several runs side by side with ratios to the first.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from skin_sim_node.scenes import Scene

from .bench_node import _pcts


def run_device_side(duration_s: float, label: str, log_dir: Path) -> dict:
    """Run bridge, simulated device and a latency observer for ``duration_s`` against a node elsewhere; the figures."""
    from skin_sim_node.bags.monitor import StreamObserver

    from .bench_node import SETTLE_S

    with Scene(log_dir) as scene:  # keeps the caller's ROS_DOMAIN_ID and discovery range
        os.environ["ROS_DOMAIN_ID"] = scene.env["ROS_DOMAIN_ID"]
        mon = StreamObserver("netns_observer", record_depth=1)
        try:
            scene.start("bridge", "bridge")
            scene.start("device", "device", "--hand-path", "press_hold_release", "--loop", "--start-delay-s", "1.0")
            mon.wait_for(lambda: len(mon.wrench) > 100, 60, "forces from the node (DDS discovery across namespaces)")
            time.sleep(SETTLE_S)  # a joining reader's stall: see SETTLE_S
            del mon.wrench[:]
            time.sleep(duration_s)
            rec = np.array(mon.wrench, dtype=np.float64).reshape(-1, 3)
        finally:
            mon.close()
    lat_ms = (rec[:, 0] - rec[:, 1]) * 1e-6
    return {
        "label": label,
        "duration_s": duration_s,
        "forces": int(rec.shape[0]),
        "rate_hz": rec.shape[0] / duration_s,
        "latency_ms": _pcts(lat_ms),
        "transports": os.environ.get("FASTDDS_BUILTIN_TRANSPORTS", "DEFAULT"),
        "discovery": os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", ""),
    }


def compare(paths: list[Path]) -> None:
    """Print the latency rows of the JSON files ``paths``, each as a ratio to the first."""
    rows = [json.loads(p.read_text()) for p in paths]
    base = rows[0]["latency_ms"]
    print("device pose -> node -> force back at the device side, ms (p50 p99 max); ratio to the first row")
    for r in rows:
        lat = r["latency_ms"]
        ratio = " / ".join(f"{a / b:.2f}x" for a, b in zip(lat, base))
        print(f"  {r['label']:>34}: {lat[0]:7.3f} {lat[1]:7.3f} {lat[2]:7.2f} | {r['rate_hz']:6.1f} forces/s | {ratio}")


def main(argv=None) -> int:
    """``skin-sim netns-role``: the device side of ``scripts/netns_scale.sh`` (``device``) or its comparison (``compare``)."""
    ap = argparse.ArgumentParser(prog="skin-sim netns-role", description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="role", required=True)
    d = sub.add_parser("device", help="bridge + simulated device + latency observer")
    d.add_argument("--duration-s", type=float, default=20.0)
    d.add_argument("--label", default="")
    d.add_argument("--json", type=Path, required=True)
    c = sub.add_parser("compare", help="print JSON rows side by side")
    c.add_argument("json", type=Path, nargs="+")
    args = ap.parse_args(argv)
    if args.role == "compare":
        compare(args.json)
        return 0
    row = run_device_side(args.duration_s, args.label, Path(tempfile.mkdtemp(prefix="skin_sim_netns_")))
    args.json.write_text(json.dumps(row))
    lat = row["latency_ms"]
    print(f"{row['label']}: {row['forces']} forces, latency p50 {lat[0]:.3f} p99 {lat[1]:.3f} max {lat[2]:.2f} ms", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
