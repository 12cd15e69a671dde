"""A browser screenshot of an oblique needle insertion (issue 22, "how it is shown").

    python -m skin_sim_node.view.needle_shot out/needle_view_30deg.png                       # the scripted needle
    python -m skin_sim_node.view.needle_shot out/needle_view_30deg.png --source node --trajectory NAME
    python -m skin_sim_node.view.needle_shot out/needle_view_15deg.png --source node --trajectory needle_oblique_15 \
        --min-punctured 0 --max-punctured 0 --min-force-n 0.8      # the tented skin before the puncture

``--source fake`` (default) drives :mod:`skin_sim_node.view.needle_fake` (a scripted NeedleState, not the model) at
``--angle-deg`` from vertical. ``--source node`` runs ``skin_sim_node`` with ``tissue.tool.shape:=needle`` and the
mock tool on ``--trajectory`` (an oblique needle path of ``skin-sim mock-tool --list``); the picture then shows
the node's own ``tissue/needle``. Either way: an isolated ROS domain, ``skin-sim view`` and headless Chromium; the
shot waits for a frame with at least ``--min-punctured`` punctured layers, holds the page on it, frames the camera
side-on to the track and draws depth at true scale (``z x`` 1, so the angle on screen is the insertion's).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from ..scenes import REPO, Proc, Scene


def _camera_js(rec: dict) -> str:
    """Side-on to the track (perpendicular to the plane of the axis and the vertical), close to its middle (mm)."""
    ax = rec["axis"]
    entry = rec["track"]["entryM"] if rec.get("track") else rec["tipM"]
    end = rec["track"]["endM"] if rec.get("track") else rec["tipM"]
    mid = [(a + b) / 2 * 1e3 for a, b in zip(entry, end)]
    h = (ax[0] ** 2 + ax[1] ** 2) ** 0.5
    side = [-ax[1] / h, ax[0] / h] if h > 1e-6 else [0.0, 1.0]  # horizontal, perpendicular to the tilt
    d = 24.0  # mm from the track: the needle's 30 mm shaft and the dimple both in the frame
    pos = [mid[0] - side[0] * d, mid[1] - side[1] * d, mid[2] + 0.3 * d]
    return f"window.skinViewCamera({json.dumps(pos)}, {json.dumps(mid)})"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m skin_sim_node.view.needle_shot", description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="PNG to write")
    ap.add_argument("--source", choices=("fake", "node"), default="fake")
    ap.add_argument("--angle-deg", type=float, default=30.0, help="fake: insertion angle from vertical")
    ap.add_argument("--trajectory", help="node: the mock tool's oblique needle trajectory")
    ap.add_argument("--params", type=Path, help="node: parameter file (default: the scenes' default.yaml)")
    ap.add_argument("--min-punctured", type=int, default=2, help="wait for at least this many punctured layers")
    ap.add_argument("--max-punctured", type=int, help="and at most this many (0: the tented skin before the puncture)")
    ap.add_argument("--min-force-n", type=float, default=0.05, help="and a force above this (the needle advancing)")
    ap.add_argument("--zscale", type=float, default=1.0, help="the page's z x (1: true angle)")
    ap.add_argument("--timeout-s", type=float, default=120.0)
    args = ap.parse_args(argv)
    if args.source == "node" and not args.trajectory:
        ap.error("--source node needs --trajectory (an oblique needle path of skin-sim mock-tool --list)")
    from .browser import Browser

    ns = "/needle_shot"
    logs = Path(tempfile.mkdtemp(prefix="skin_sim_needle_shot_"))
    with Scene(logs) as scene:
        if args.source == "fake":
            argv_fake = [sys.executable, "-m", "skin_sim_node.view.needle_fake", "--namespace", ns]
            argv_fake += ["--angle-deg", f"{args.angle_deg}"]
            log = logs / "needle_fake.log"
            popen = subprocess.Popen(argv_fake, stdout=open(log, "w"), stderr=subprocess.STDOUT, env=scene.env, cwd=REPO)
            scene.procs.append(Proc("needle_fake", argv_fake, popen, log))
        else:
            extra = ["-r", f"__ns:={ns}", "-p", "tissue.tool.shape:=needle"]
            node = scene.node(*extra, **({"params": args.params} if args.params else {}))
            scene.wait_for_log(node, "live:", timeout_s=180)
        view = scene.start("view", "view", "--namespace", ns, "--port", "0")
        scene.wait_for_log(view, "skin-sim view: http", timeout_s=60)
        url = view.log().split("skin-sim view: ", 1)[1].split()[0]
        with Browser(url) as b:
            b.wait_for("window.skinView && window.skinView.gridFrames > 0", args.timeout_s, "a tissue grid")
            if args.source == "node":  # the insertion starts once the page shows the tissue (not before Chromium is up)
                scene.start("mock_tool", "mock-tool", "--trajectory", args.trajectory, "--ros-args", "-r", f"__ns:={ns}")
            b.evaluate(f"(() => {{ const z = document.getElementById('zscale'); z.value = '{args.zscale:g}'; "
                       "z.dispatchEvent(new Event('change')); return true; })()")  # fmt: skip
            cond = f"window.skinView.needle && window.skinView.needle.segments.length >= {args.min_punctured}"
            if args.max_punctured is not None:
                cond += f" && window.skinView.needle.segments.length <= {args.max_punctured}"
            b.wait_for(cond, args.timeout_s, f"a needle with {args.min_punctured} punctured layers")
            pressing = f"{cond} && window.skinView.force > {args.min_force_n}"
            b.hold_when(pressing, args.timeout_s, f"a punctured frame with a force above {args.min_force_n} N")
            b.evaluate(_camera_js(b.evaluate("window.skinView.needle")))
            n = b.evaluate("window.skinView.renders || 0")
            b.wait_for(f"(window.skinView.renders || 0) > {n}", 30, "a render from the new camera")
            args.out.parent.mkdir(parents=True, exist_ok=True)
            shot = b.screenshot(args.out)
            text = b.evaluate("window.skinView.needleText")
            b.release()
    print(f"needle screenshot {shot} ({args.source}, logs {logs}):\n{text}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
