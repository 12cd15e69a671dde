"""skin-sim view: wire format, WebSocket, bag timeline, HTTP API, and the real page in headless Chromium.

The browser tests drive Debian's ``chromium`` over the DevTools protocol; without a browser they skip
with the reason. The live test runs real processes (node, mock tool, view) over DDS.
"""

from __future__ import annotations

import json
import os
import shutil
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from conftest import served

from skin_sim_node.bags.compare import read_outputs
from skin_sim_node.view import frames, ws
from skin_sim_node.view.bag import BagData, BagSource, find_topic
from skin_sim_node.view.browser import find_browser
from skin_sim_node.view.live import parse_value

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "tests" / "data" / "press_all_layers"
BAGS = [DATA / "input", DATA / "expected"]
SHOTS = Path(os.environ.get("SKIN_SIM_SHOTS", REPO / "out" / "view_shots"))
"""Where the browser tests write their screenshots: out/ (untracked), so a test run rewrites no tracked file;
``SKIN_SIM_SHOTS=docs/view`` regenerates the ones docs/view.md shows."""
needs_browser = pytest.mark.skipif(find_browser() is None, reason="no Chromium on PATH (CI: apt-get install chromium)")


# --- pure parts ------------------------------------------------------------------------------
def test_frame_round_trip_with_and_without_grid(rng):
    grid = rng.normal(size=(7, 5, 3)).astype(np.float32)
    h, g = frames.decode_frame(frames.encode_frame({"force": [0, 0, 1.5], "seq": 3}, grid))
    assert h["force"] == [0, 0, 1.5] and h["grid"] == {"ny": 7, "nx": 5}
    np.testing.assert_array_equal(g, grid)
    data = frames.encode_frame({"seq": 4})
    assert (len(data) - 8) % 4 == 0  # the grid block starts 4-byte aligned (Float32Array view in the page)
    assert frames.decode_frame(data) == ({"seq": 4}, None)
    with pytest.raises(ValueError, match=r"\(ny, nx, 3\)"):
        frames.encode_frame({}, np.zeros((4, 4)))


def test_websocket_accept_key_is_rfc6455_example():
    assert ws.accept_key("dGhlIHNhbXBsZSBub25jZQ==") == "s3pPLMBiTxaQ9kYGzzhZRbK+xOo="  # RFC 6455 section 1.3


def test_mask_is_an_involution(rng):
    data = rng.integers(0, 256, 1001, dtype=np.uint8).tobytes()
    key = b"\x01\x82\xfe\x33"
    masked = ws.apply_mask(data, key)
    assert masked != data and ws.apply_mask(masked, key) == data
    assert masked[:4] == bytes(a ^ b for a, b in zip(data[:4], key))


def test_parse_value_follows_the_parameter_type():
    assert parse_value("2.5", 3) == 2.5 and isinstance(parse_value("3", 3), float)
    assert parse_value("7", 2) == 7 and parse_value("true", 1) is True
    assert parse_value("abc", 3) == "abc"  # sent as a string: the node's type check answers
    assert parse_value("1.5", 2) == "1.5"


def test_diag_message_keeps_regime_and_counts():
    d = frames.diag_message(
        1, "late", {"achieved_rate_hz": "990.0", "regime_beyond_fat": "2", "count_teleport": "1", "warmup_s": "1.0"}
    )
    assert d["values"] == {"achieved_rate_hz": "990.0"}
    assert d["regime"] == {"beyond_fat": "2"} and d["counts"] == {"teleport": "1"} and d["level"] == 1


def test_find_topic_in_any_namespace():
    types = {
        "/bed1/tool/wrench": "geometry_msgs/msg/WrenchStamped",
        "/tool/pose": "geometry_msgs/msg/PoseStamped",
        "/x/tool/wrench": "std_msgs/msg/String",
    }
    assert find_topic(types, "tool_wrench") == "/bed1/tool/wrench"
    assert find_topic(types, "tool_pose") == "/tool/pose"
    assert find_topic(types, "layer_heights") is None


# --- bag timeline ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def bag():
    return BagData(BAGS)


def test_bag_timeline_matches_the_bag_readers(bag):
    forces, grids = read_outputs(DATA / "expected")
    assert len(bag.grids) == len(grids) and len(bag.wrench_t) == len(forces)
    fz = np.array([forces[k][2] for k in sorted(forces)])
    np.testing.assert_allclose(bag.wrench[:, 2], fz)
    peak = int(np.argmax(fz))
    h = bag.header_at(bag.wrench_t[peak])
    assert h["force"][2] == pytest.approx(fz.max())
    assert h["depth_m"] > 0 and h["tool"][2] < 0  # the tool is in the tissue at peak force
    tl = bag.timeline()
    assert tl["duration_s"] == pytest.approx(bag.duration_s)
    assert max(tl["force_n"]) <= fz.max() + 0.5e-6  # the timeline rounds to 1 uN


def test_bag_seek_sends_the_grid_at_that_time(bag):
    src = BagSource(BAGS)
    src.data = bag
    i = len(bag.grids) // 2
    src.seek(bag.grid_t[i] + 1e-4)
    h, data, _ = src.frame_at(src.t_s)
    h2, g = frames.decode_frame(data)
    assert h2["grid_index"] == i
    np.testing.assert_array_equal(g, bag.grids[i])
    _, data, _ = src.frame_at(src.t_s)  # same grid again: not resent
    assert frames.decode_frame(data)[1] is None
    assert src.seek(1e9)["t_s"] == pytest.approx(bag.duration_s)


def test_server_streams_frames_and_answers_the_api(bag):
    src = BagSource(BAGS, rate_hz=50)
    with served(src, 20.0) as srv:
        page = urllib.request.urlopen(srv.url, timeout=5).read().decode()
        assert "three.module.min.js" in page and "app.js" in page
        params = json.load(urllib.request.urlopen(srv.url + "api/params", timeout=5))
        assert not params["ok"] and "no parameter service" in params["reason"]
        c = ws.connect(f"ws://127.0.0.1:{srv.port}/ws")
        info = json.loads(c.recv())
        assert info["type"] == "info" and info["mode"] == "bag"
        timeline = json.loads(c.recv())
        assert timeline["type"] == "timeline"
        req = urllib.request.Request(srv.url + "api/seek", data=json.dumps({"t_s": float(bag.grid_t[-1])}).encode())
        assert json.load(urllib.request.urlopen(req, timeout=5))["ok"]
        end = time.monotonic() + 10
        got = None
        while time.monotonic() < end:
            m = c.recv()
            if isinstance(m, bytes):
                h, g = frames.decode_frame(m)
                if h.get("grid_index") == len(bag.grids) - 1 and g is not None:
                    got = g
                    break
        assert got is not None, "no frame with the last grid after seeking to it"
        np.testing.assert_array_equal(got, bag.grids[-1])
        c.close()


def test_live_frame_carries_the_largest_force_since_the_last_frame():
    """A 1 ms spike between two 30 Hz frames reaches the page (the newest wrench alone would hide it)."""
    from skin_sim_node.bags.io import new_message
    from skin_sim_node.view.live import LiveSource

    src = LiveSource.__new__(LiveSource)  # no rclpy: only the callbacks and the header
    src.pose = src.wrench = src.contact = None
    src.form, src.frames = "layered", 0
    for fz in (0.1, 8.9, 0.2):
        m = new_message("geometry_msgs/msg/WrenchStamped")
        m.wrench.force.z = fz
        src._on_wrench(m)
    h = src.header()
    assert h["force_max"] == 8.9 and h["force"][2] == 0.2
    assert "force_max" not in src.header()  # no wrench since: the page shows the newest


def test_bag_frame_while_playing_carries_the_largest_force_since_the_last_frame(bag):
    src = BagSource(BAGS)
    src.data = bag
    peak = int(np.argmax(bag.wrench[:, 2]))
    t0, t1 = float(bag.wrench_t[peak - 20]), float(bag.wrench_t[peak + 20])
    src.frame_at(t0)
    src.playing = True
    h, _, _ = src.frame_at(t1)
    assert h["force_max"] == pytest.approx(bag.wrench[peak, 2]) and h["force"][2] < h["force_max"]


# --- the real page in headless Chromium --------------------------------------------------------
def _tissue_pixels(png: Path) -> tuple[float, float]:
    """(fraction of the 3D area that is not background, fraction that is skin-coloured: r > g > b, bright)."""
    import matplotlib.image as mpimg

    img = mpimg.imread(png)[..., :3]
    area = img[:, : int(img.shape[1] * 0.65)]  # the scene; the side panel is on the right
    bg = np.array([0x1D, 0x21, 0x27]) / 255
    not_bg = np.abs(area - bg).sum(axis=2) > 0.08
    r, g, b = area[..., 0], area[..., 1], area[..., 2]
    skin = (r > 0.45) & (r > g + 0.03) & (g > b) & not_bg
    return float(not_bg.mean()), float(skin.mean())


LAYER_SRGB = np.array([[0.95, 0.79, 0.65], [0.85, 0.47, 0.48], [0.96, 0.88, 0.56]])  # app.js LAYER_RGB, unlit in the cut


def _scene_pixels(png: Path) -> dict:
    """Pixel classes of the 3D area (left of the side panel, without the overlay line and the timeline).

    ``arrow``: the force arrow's unlit cyan, with its vertical extent in rows; ``tool``: the tool's steel blue,
    with its silhouette's median width (px) in the lower quarter and the upper half of its rows; ``layers``:
    pixels of each of the three layer colours of the cut (unlit, so exact).
    """
    import matplotlib.image as mpimg

    img = mpimg.imread(png)[..., :3]
    area = img[30 : img.shape[0] - 50, : int(img.shape[1] * 0.7)]
    r, g, b = area[..., 0], area[..., 1], area[..., 2]
    cyan = (r < 0.3) & (g > 0.7) & (b > 0.8)
    tool = (b > r + 0.08) & (b >= g) & (area.mean(axis=2) > 0.2) & ~cyan
    cols = tool.sum(axis=0)
    tool &= cols > 0.05 * cols.max(initial=0)  # drop stray edge pixels (the arrow's anti-aliased rim)
    rows = np.where(tool.sum(axis=1) > 3)[0]
    widths = tool[rows].sum(axis=1)
    n = len(rows)
    out = {
        "arrow": int(cyan.sum()),
        "arrow_rows": int(np.ptp(np.where(cyan.any(axis=1))[0])) if cyan.any() else 0,
        "tool": int(tool.sum()),
        "tool_width_low": float(np.median(widths[int(0.75 * n) :])) if n > 8 else 0.0,
        "tool_width_high": float(np.median(widths[: n // 2])) if n > 8 else 0.0,
        "layers": [int((np.abs(area - c).max(axis=2) < 0.04).sum()) for c in LAYER_SRGB],
    }
    return out


def _seek(b, t_s: float, force_n: float) -> None:
    b.evaluate(f"fetch('/api/seek', {{method: 'POST', body: JSON.stringify({{t_s: {t_s}}})}}).then(r => r.json())")
    b.wait_for(f"Math.abs(window.skinView.force - {force_n}) < 1e-4", 20, f"the force {force_n:.4f} N on the page")
    _rendered(b)


def _rendered(b) -> None:
    """Wait until the page has rendered every frame it has received (the scene is what the DOM says)."""
    n = b.evaluate("window.skinView.frames")
    b.wait_for(f"window.skinView.renderedFrames >= {n}", 20, "a render of the last frame")


@pytest.fixture()
def bag_page():
    from skin_sim_node.view.browser import Browser

    src = BagSource(BAGS)
    with served(src) as srv, Browser(srv.url) as b:
        yield src, b


@needs_browser
def test_bag_page_scrubs_to_a_frame(bag_page, tmp_path):
    src, b = bag_page
    b.wait_for("window.skinView && window.skinView.gridFrames > 0", 60, "the first grid")
    d = src.data
    peak = int(np.argmax(d.wrench[:, 2]))
    t_peak = float(d.wrench_t[peak])
    _seek(b, t_peak, d.wrench[peak, 2])
    shown = b.evaluate("document.getElementById('force').textContent")
    assert float(shown) == pytest.approx(d.wrench[peak, 2], abs=1e-4)
    label = b.evaluate("document.getElementById('tlabel').textContent")
    assert label.startswith(f"{t_peak:.3f}")
    not_bg, skin = _tissue_pixels(b.screenshot(tmp_path / "bag.png"))
    assert not_bg > 0.08 and skin > 0.05, (not_bg, skin)
    # a held page keeps its frame (what a screenshot needs): a seek to the start reaches the page, is queued, not shown
    b.hold_when("window.skinView.force > 0", 5, "the peak frame")
    held = b.evaluate("window.skinView.heldFrames || 0")
    b.evaluate("fetch('/api/seek', {method: 'POST', body: JSON.stringify({t_s: 0.0})}).then(r => r.json())")
    b.wait_for(f"(window.skinView.heldFrames || 0) > {held}", 20, "a frame queued while held")
    assert float(b.evaluate("document.getElementById('force').textContent")) == pytest.approx(d.wrench[peak, 2], abs=1e-4)
    b.release()  # the frame that came while held is applied then (it may carry a grid: no frame is lost)
    b.wait_for(f"Math.abs(window.skinView.force - {float(d.wrench[0, 2])}) < 1e-4", 20, "the start frame once released")
    assert b.evaluate("window.skinView.t_s") == pytest.approx(0.0, abs=1e-3)


@needs_browser
def test_bag_page_opens_at_its_first_grid_with_the_tool_in_frame(bag_page, tmp_path):
    """No seek: the first frame the page shows is the bag's first grid (not t = 0 before any grid), and the
    lifted tool is drawn at its true height, inside the picture."""
    src, b = bag_page
    b.wait_for("window.skinView && window.skinView.gridFrames > 0", 60, "the first grid")
    _rendered(b)
    assert b.evaluate("window.skinView.t_s") == pytest.approx(float(src.data.grid_t[0]), abs=1e-6)
    shot = b.screenshot(tmp_path / "first.png")
    not_bg, skin = _tissue_pixels(shot)
    assert not_bg > 0.08 and skin > 0.05, (not_bg, skin)
    z_tool_mm = 1e3 * float(src.data.header_at(src.data.grid_t[0])["tool"][2])
    assert z_tool_mm > 0 and b.evaluate("window.skinView.toolZDrawnMm") == pytest.approx(z_tool_mm)  # not x z-scale
    assert _scene_pixels(shot)["tool"] > 500  # the tool is in the frame


@needs_browser
def test_bag_page_force_arrow_tool_cut_and_scale(bag_page, tmp_path):
    """From the pixels: the arrow is visible and longer at a larger force, the flat punch is a cylinder, the cut
    shows three layer colours; from the DOM: the arrow's newton label, the layer legend, the displacement scale."""
    src, b = bag_page
    d = src.data
    b.wait_for("window.skinView && window.skinView.gridFrames > 0", 60, "the first grid")
    # the picture shows the grid of the instant it names: the deepest press among the bag's grid instants (the hold at
    # 4 mm), not the largest wrench, which comes at the end of the press, between two grids (0.2-0.3 s after the last)
    at_grids = [int(np.argmin(np.abs(d.wrench_t - g))) for g in d.grid_t]
    peak = min(at_grids, key=lambda i: (d.header_at(d.wrench_t[i])["tool"][2], -d.wrench[i, 2]))
    z_deepest = d.header_at(d.wrench_t[int(np.argmax(d.wrench[:, 2]))])["tool"][2]  # the press's end
    assert d.header_at(d.wrench_t[peak])["tool"][2] <= z_deepest + 1e-6 and d.wrench[peak, 2] > 0
    low = int(np.argmax(d.wrench[:, 2] > 0.15 * d.wrench[peak, 2]))  # on the way down, at 15 % of the peak
    _seek(b, float(d.wrench_t[low]), d.wrench[low, 2])
    at_low = _scene_pixels(b.screenshot(tmp_path / "low.png"))
    _seek(b, float(d.wrench_t[peak]), d.wrench[peak, 2])
    assert abs(b.evaluate("window.skinView.gridDtS")) < 1e-3  # the grid drawn is the tool's instant
    SHOTS.mkdir(parents=True, exist_ok=True)
    shot = b.screenshot(SHOTS / "view_bag_peak.png")
    at_peak = _scene_pixels(shot)
    assert at_low["arrow"] > 50 and at_peak["arrow"] > 50, (at_low, at_peak)
    lengths = [b.evaluate("window.skinView.arrowLenMm")]
    assert at_peak["arrow_rows"] > 1.5 * at_low["arrow_rows"], (at_low, at_peak)  # 6.7x the force: a longer arrow
    label = b.evaluate("document.getElementById('arrow-label').textContent")
    assert label == f"{d.wrench[peak, 2]:.3f} N" and lengths[0] > 10
    # a clear "depth reached" (4 mm: past the dermis, whose bottom is at rest 0.075 + 1.2 mm deep)
    reached = b.evaluate("document.getElementById('tip-layer').textContent")
    assert reached == "fat (its rest depth 1.275-5.275 mm)", reached
    # the default tool is a flat punch: a cylinder, no wider at its bottom than above (perspective narrows the
    # farther bottom: 0.76 measured); the old ball of radius r on a 0.6 r shaft was 1.7x wider at the bottom
    assert b.evaluate("window.skinView.toolShape") == "cylinder" and src.info()["tool_shape"] == "flat"
    assert at_peak["tool"] > 500 and 0.6 < at_peak["tool_width_low"] / at_peak["tool_width_high"] < 1.1, at_peak
    # three coloured bands in the cut while pressing, and a legend naming them
    assert b.evaluate("window.skinView.cutBands") is True
    assert all(n > 300 for n in at_peak["layers"]), at_peak["layers"]
    legend = b.evaluate("document.getElementById('legend').textContent")
    assert all(name in legend for name in ("epidermis", "dermis", "fat"))
    # each checkbox sits on one line with its label (a wrapped label left the box alone on the line above)
    boxes = b.evaluate("""(() => [...document.querySelectorAll('label')].filter((l) => l.querySelector('input[type=checkbox]'))
        .map((l) => { const c = l.querySelector('input').getBoundingClientRect(), r = l.getBoundingClientRect();
                      return {text: l.textContent.trim(), one_line: r.height < 2 * Math.max(c.height, 12)}; }))()""")
    assert len(boxes) >= 4 and all(x["one_line"] for x in boxes), boxes
    # without the cut, the bands go: the colours came from the cut
    b.evaluate("(() => { const c = document.getElementById('cutaway'); c.click(); return c.checked; })()")
    b.wait_for("window.skinView.renderedCut === false", 20, "a render without the cut")
    assert _scene_pixels(b.screenshot(tmp_path / "nocut.png"))["layers"][0] < 0.5 * at_peak["layers"][0]
    # displacement colouring has a scale in mm
    b.evaluate(
        "(() => { const s = document.getElementById('colour'); s.value = 'disp'; s.dispatchEvent(new Event('change')); })()"
    )
    b.wait_for("document.getElementById('disp-scale').style.display === 'block'", 20, "the displacement scale")
    text = b.evaluate("document.getElementById('disp-max').textContent")
    assert text.endswith("mm deeper than rest") and float(text.split()[0]) > 0.5, text


@pytest.mark.ros
@needs_browser
def test_live_page_shows_tissue_force_and_rejection(ros_domain, tmp_path):
    """Node + mock tool pressing + view in namespace /view_test; Chromium opens the page."""
    from skin_sim_node.scenes import Scene
    from skin_sim_node.view.browser import Browser

    ns = "/view_test"
    with Scene(tmp_path / "logs") as scene:
        assert scene.env["ROS_DOMAIN_ID"] == os.environ["ROS_DOMAIN_ID"]
        # the stamp-age check off: beside Chromium's software rendering (up to 1.2 cores) the mock tool's poses were seen
        # reaching the node 1.1 s late for minutes in full-suite runs (2026-12-03), which the node rightly rejects as
        # stale input; this test is about the page (the stamp-age policy: tests/test_session.py)
        node = scene.node("-r", f"__ns:={ns}", "-p", "max_stamp_age_s:=0.0")
        scene.wait_for_log(node, "live:", timeout_s=180)
        tool = scene.start(
            "mock_tool", "mock-tool", "--trajectory", "press_hold_release", "--loop", "--ros-args", "-r", f"__ns:={ns}"
        )
        view = scene.start("view", "view", "--namespace", ns, "--port", "0")
        scene.wait_for_log(view, "skin-sim view: http", timeout_s=60)
        url = view.log().split("skin-sim view: ", 1)[1].split()[0]
        with Browser(url) as b:
            b.wait_for("window.skinView && window.skinView.gridFrames > 2", 60, "tissue grids on the page")
            forces: list[float] = []
            # until a press and a release were both read (the loop cycles every 2.5 s); not a fixed window: each read
            # waits for the page's main thread, which a loaded CPU slows (a scheduling-free condition, 120 s at most)
            end = time.monotonic() + 120.0
            while time.monotonic() < end:
                text = b.evaluate("document.getElementById('force').textContent")
                if text not in ("-", None):
                    forces.append(float(text))
                top = max(forces, default=0.0)
                if len(forces) >= 5 and top > 0.01 and min(forces) < 0.2 * top and forces[-1] > 0.01:
                    break
                time.sleep(0.05)
            assert len(forces) >= 5, forces
            assert max(forces) > 0.01 and min(forces) < 0.2 * max(forces), (min(forces), max(forces))
            # screenshot while pressing: the canvas shows the tissue
            pressed = float(np.median([f for f in forces if f > 0.01]))  # the hold force (the press may start with a spike)
            SHOTS.mkdir(parents=True, exist_ok=True)
            # the docs picture shows a press with the grid of that instant: pressed and the grid within 50 ms of the
            # tool, both before and after the shot. On a loaded CPU the display worker's grids can lag the tool by
            # up to a second; then the shot stays in tmp_path (the docs keep theirs) and the test says so.
            # The page is held on the frame that met the condition (it takes no new frame until released).
            pressed_now = f"window.skinView.force > 0.8 * {pressed} && Math.abs(window.skinView.gridDtS) < 0.05"
            try:
                b.hold_when(pressed_now, 60, "a pressed frame with a grid within 50 ms of the tool")
                good = True
            except TimeoutError:
                b.hold_when(f"window.skinView.force > 0.8 * {pressed}", 20, "a pressed frame")
                good = False
            _rendered(b)
            shot = b.screenshot(tmp_path / "view_live.png")
            assert b.evaluate(f"window.skinView.force > 0.8 * {pressed}")  # still the held, pressed frame
            b.release()
            if good:
                shutil.copyfile(shot, SHOTS / "view_live.png")
            else:
                print(f"view_live.png not saved to {SHOTS}: no pressed frame with a grid within 50 ms of the tool (load?)")
            not_bg, skin = _tissue_pixels(shot)
            assert not_bg > 0.08 and skin > 0.05, (not_bg, skin)
            assert b.evaluate("document.getElementById('mode').textContent") == f"live {ns}"
            # layered form, no tissue/contact reader (it would make the node publish it every tick): all 3 layers
            b.wait_for("document.getElementById('layers').textContent === '3'", 20, "3 layers during a press")
            assert b.evaluate("window.skinView.diag !== null && window.skinView.diag.values.achieved_rate_hz !== undefined")
            # the tool as the node configures it, its arrow labelled in newtons while pressing
            b.wait_for(
                "window.skinView.toolShape === 'cylinder' && window.skinView.arrowLenMm > 0", 20, "the punch and its arrow"
            )
            assert b.evaluate("document.getElementById('arrow-label').textContent").endswith(" N")
            reached = b.evaluate("document.getElementById('tip-layer').textContent")
            assert reached.split()[0] in ("none", "epidermis", "dermis", "fat"), reached
            # parameters come from the node at run time; a bad value typed into the page shows the node's reason. The tool
            # stops first: beside Chromium and a 1 kHz tool, the node in a full-suite CI run answered no parameter call
            # for 18 s (three sets of two 3 s calls, 2026-12-03); what is checked here is the page and the node's reason
            scene.stop(tool)
            b.wait_for(
                "document.querySelector('input[data-name=\"tissue.layers.dermis.stiffness_n_per_m\"]') !== null",
                60,
                "the stiffness field",
            )
            # the panel fits the 1280 x 800 window: every "set" button lies inside it, nothing scrolls sideways
            inside = b.evaluate("""(() => { const w = window.innerWidth, bs = [...document.querySelectorAll('button[data-set]')];
                return {n: bs.length, out: bs.filter((e) => e.getBoundingClientRect().right > w).length,
                        scroll: document.documentElement.scrollWidth - w,
                        side: document.getElementById('side').scrollWidth - document.getElementById('side').clientWidth}; })()""")
            assert inside["n"] >= 5 and inside["out"] == 0 and inside["scroll"] <= 0 and inside["side"] <= 0, inside

            def set_param(name: str, value: str) -> dict:
                """The page's set; a node starved beside Chromium may miss the view's 3 s parameter call (a full-suite
                run, 2026-12-03): asked again then, at most three times. The node's answer is what is checked."""
                for _ in range(3):
                    res = b.evaluate(f"window.skinViewSetParam('{name}', '{value}')")
                    if "no answer from" not in str(res.get("reason", "")):
                        break
                return res

            r = set_param("tissue.layers.dermis.stiffness_n_per_m", "-5")
            assert r["ok"] is False
            shown = b.evaluate("document.getElementById('param-result').textContent")
            assert "rejected" in shown and "must be > 0" in shown, shown
            # scrolled down to the last parameter, the rejection stays in view (sticky above the list)
            seen = b.evaluate("""(() => { const side = document.getElementById('side'); side.scrollTop = side.scrollHeight;
                const r = document.getElementById('param-result').getBoundingClientRect();
                return r.top >= 0 && r.bottom <= window.innerHeight && r.height > 0; })()""")
            assert seen is True
            r = set_param("tissue.layers.dermis.damping_n_s_per_m", "soft")
            # the schema's reason, as at start-up (issue 29; it was rclpy's "wrong parameter type")
            assert r["ok"] is False and r["reason"] == "tissue.layers.dermis.damping_n_s_per_m: expected a number, got 'soft'", r
            # a valid set: the node rebuilds the tissue, which beside Chromium in a full-suite run took it about 12 s, past
            # the view's 3 s call (2026-12-03). Then the set is not sent again (each would rebuild again): the node's
            # own parameter list, read through the view until the node answers (60 s at most), must show the value
            r = b.evaluate("window.skinViewSetParam('tissue.lod.tolerance_m', '2e-5')")
            if "no answer from" in str(r.get("reason", "")):
                end = time.monotonic() + 60.0
                while time.monotonic() < end:
                    got = b.evaluate("fetch('/api/params').then((x) => x.json())")
                    vals = {p["name"]: p["value"] for p in got.get("params", [])} if got.get("ok") else {}
                    if "tissue.lod.tolerance_m" in vals:
                        r = {"ok": float(vals["tissue.lod.tolerance_m"]) == 2e-5, "applied late": vals["tissue.lod.tolerance_m"]}
                        break
                    time.sleep(1.0)
            assert r["ok"] is True, r
        assert "parameter change rejected" in node.log()


def test_bad_bag_is_one_line_error(tmp_path, capsys):
    from skin_sim_node.view import main

    assert main([str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no such bag" in err[0]
    (tmp_path / "empty").mkdir()
    assert main([str(tmp_path / "empty")]) == 2
    assert "not a rosbag2 folder" in capsys.readouterr().err


@pytest.mark.ros
@needs_browser
def test_page_opened_before_the_node_lists_its_parameters_once_it_runs(ros_domain, tmp_path):
    """A view (and its page) started before the node shows why there are no parameters, then lists them."""
    from skin_sim_node.scenes import Scene
    from skin_sim_node.view.browser import Browser

    ns = "/view_late"
    with Scene(tmp_path / "logs") as scene:
        view = scene.start("view", "view", "--namespace", ns, "--port", "0")
        scene.wait_for_log(view, "skin-sim view: http", timeout_s=60)
        url = view.log().split("skin-sim view: ", 1)[1].split()[0]
        with Browser(url) as b:
            b.wait_for("document.getElementById('params').textContent.includes('not found')", 60, "the reason")
            node = scene.node("-r", f"__ns:={ns}")
            scene.wait_for_log(node, "live:", timeout_s=180)
            b.wait_for(
                "document.querySelector('input[data-name=\"tissue.layers.dermis.stiffness_n_per_m\"]') !== null",
                60,
                "the stiffness field once the node runs",
            )
            assert b.evaluate("document.getElementById('param-node').textContent") == f"{ns}/skin_sim_node"
