"""skin-sim view: wire format, WebSocket, bag timeline, HTTP API, and the real page in headless Chromium.

The browser tests drive Debian's ``chromium`` over the DevTools protocol; without a browser they skip
with the reason. The live test runs real processes (node, mock tool, view) over DDS.
"""

from __future__ import annotations

import json
import os
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from skin_sim_node.bags.compare import read_outputs
from skin_sim_node.view import frames, ws
from skin_sim_node.view.bag import BagData, BagSource, find_topic
from skin_sim_node.view.browser import find_browser
from skin_sim_node.view.live import parse_value
from skin_sim_node.view.server import ViewServer

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "tests" / "data" / "press_all_layers"
BAGS = [DATA / "input", DATA / "expected"]
SHOTS = REPO / "docs" / "view"
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
    d = frames.diag_message(1, "late", {"achieved_rate_hz": "990.0", "regime_beyond_fat": "2", "count_teleport": "1",
                                        "warmup_s": "1.0"})  # fmt: skip
    assert d["values"] == {"achieved_rate_hz": "990.0"}
    assert d["regime"] == {"beyond_fat": "2"} and d["counts"] == {"teleport": "1"} and d["level"] == 1


def test_find_topic_in_any_namespace():
    types = {"/bed1/tool/wrench": "geometry_msgs/msg/WrenchStamped", "/tool/pose": "geometry_msgs/msg/PoseStamped",
             "/x/tool/wrench": "std_msgs/msg/String"}  # fmt: skip
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
    fz = np.array([forces[k] for k in sorted(forces)])
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
    srv = ViewServer(src, port=0).start()
    import threading

    t = threading.Thread(target=src.run, args=(srv, 20.0), daemon=True)
    t.start()
    try:
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
    finally:
        src.stop()
        t.join(timeout=5)
        srv.close()


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


@needs_browser
def test_bag_page_scrubs_to_a_frame(tmp_path):
    from skin_sim_node.view.browser import Browser

    src = BagSource(BAGS)
    srv = ViewServer(src, port=0).start()
    import threading

    t = threading.Thread(target=src.run, args=(srv, 120.0), daemon=True)
    t.start()
    try:
        with Browser(srv.url) as b:
            b.wait_for("window.skinView && window.skinView.gridFrames > 0", 60, "the first grid")
            d = src.data
            peak = int(np.argmax(d.wrench[:, 2]))
            t_peak = float(d.wrench_t[peak])
            b.evaluate(f"fetch('/api/seek', {{method: 'POST', body: JSON.stringify({{t_s: {t_peak}}})}}).then(r => r.json())")
            shown = b.wait_for(f"Math.abs(parseFloat(document.getElementById('force').textContent) - {d.wrench[peak, 2]}) < 1e-4 "
                               "&& document.getElementById('force').textContent", 20, "the peak force on the page")  # fmt: skip
            assert float(shown) == pytest.approx(d.wrench[peak, 2], abs=1e-4)
            label = b.evaluate("document.getElementById('tlabel').textContent")
            assert label.startswith(f"{t_peak:.3f}")
            time.sleep(0.5)
            not_bg, skin = _tissue_pixels(b.screenshot(tmp_path / "bag.png"))
            assert not_bg > 0.08 and skin > 0.05, (not_bg, skin)
    finally:
        src.stop()
        t.join(timeout=5)
        srv.close()


@pytest.mark.ros
@needs_browser
def test_live_page_shows_tissue_force_and_rejection(ros_domain, tmp_path):
    """Node + mock tool pressing + view in namespace /view_test; Chromium opens the page."""
    from skin_sim_node.scenes import Scene
    from skin_sim_node.view.browser import Browser

    ns = "/view_test"
    with Scene(tmp_path / "logs") as scene:
        assert scene.env["ROS_DOMAIN_ID"] == os.environ["ROS_DOMAIN_ID"]
        node = scene.node("-r", f"__ns:={ns}")
        scene.wait_for_log(node, "live:", timeout_s=180)
        scene.start("mock_tool", "mock-tool", "--trajectory", "press_hold_release", "--loop", "--ros-args", "-r", f"__ns:={ns}")
        view = scene.start("view", "view", "--namespace", ns, "--port", "0")
        scene.wait_for_log(view, "skin-sim view: http", timeout_s=60)
        url = view.log().split("skin-sim view: ", 1)[1].split()[0]
        with Browser(url) as b:
            b.wait_for("window.skinView && window.skinView.gridFrames > 2", 60, "tissue grids on the page")
            forces = []
            end = time.monotonic() + 8.0  # > one press/hold/release cycle (2.5 s)
            while time.monotonic() < end:
                text = b.evaluate("document.getElementById('force').textContent")
                if text not in ("-", None):
                    forces.append(float(text))
                time.sleep(0.05)
            assert len(forces) >= 5, forces  # each read waits for the page's main thread (busy rendering on a CPU)
            assert max(forces) > 0.01 and min(forces) < 0.2 * max(forces), (min(forces), max(forces))
            # screenshot while pressing: the canvas shows the tissue
            pressed = float(np.median([f for f in forces if f > 0.01]))  # the hold force (the press may start with a spike)
            SHOTS.mkdir(parents=True, exist_ok=True)
            for _ in range(5):  # a shot taken while the page still shows the press (the page lags on a loaded CPU)
                b.wait_for(f"window.skinView.force > 0.8 * {pressed}", 20, "a pressed frame")
                shot = b.screenshot(SHOTS / "view_live.png")
                if b.evaluate(f"window.skinView.force > 0.5 * {pressed}"):
                    break
            not_bg, skin = _tissue_pixels(shot)
            assert not_bg > 0.08 and skin > 0.05, (not_bg, skin)
            assert b.evaluate("document.getElementById('mode').textContent") == f"live {ns}"
            # layered form, no tissue/contact reader (it would make the node publish it every tick): all 3 layers
            b.wait_for("document.getElementById('layers').textContent === '3'", 20, "3 layers during a press")
            assert b.evaluate("window.skinView.diag !== null && window.skinView.diag.values.achieved_rate_hz !== undefined")
            # parameters come from the node at run time; a bad value typed into the page shows the node's reason
            b.wait_for("document.querySelector('input[data-name=\"tissue.layers.dermis.stiffness_n_per_m\"]') !== null",
                       60, "the stiffness field")  # fmt: skip
            r = b.evaluate("window.skinViewSetParam('tissue.layers.dermis.stiffness_n_per_m', '-5')")
            assert r["ok"] is False
            shown = b.evaluate("document.getElementById('param-result').textContent")
            assert "rejected" in shown and "must be > 0" in shown, shown
            r = b.evaluate("window.skinViewSetParam('tissue.layers.dermis.damping_n_s_per_m', 'soft')")
            assert r["ok"] is False and "type" in r["reason"].lower(), r
            r = b.evaluate("window.skinViewSetParam('tissue.lod.tolerance_m', '2e-5')")
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
            b.wait_for("document.querySelector('input[data-name=\"tissue.layers.dermis.stiffness_n_per_m\"]') !== null",
                       60, "the stiffness field once the node runs")  # fmt: skip
            assert b.evaluate("document.getElementById('param-node').textContent") == f"{ns}/skin_sim_node"
