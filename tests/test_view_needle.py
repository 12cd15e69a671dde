"""skin-sim view with a needle (issue 22): the needle, its track and the punctured layers, live and from a bag.

The page's scene is read back through ``window.skinViewNeedle()`` (the meshes' world endpoints, drawn mm) and
compared with the geometry of the scripted insertion (``skin_sim_node.view.needle_fake``: a real NeedleState and
PoseStamped publisher, not the model). Browser tests skip without Chromium, as in tests/test_view.py.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import served

from skin_sim_node.view import frames
from skin_sim_node.view.bag import BagData, BagSource, register_needle_type
from skin_sim_node.view.browser import find_browser
from skin_sim_node.view.needle_fake import FAKE_RUPTURE_DIMPLE_M, NeedleScript, fill_needle

needs_browser = pytest.mark.skipif(find_browser() is None, reason="no Chromium on PATH (CI: apt-get install chromium)")
NEEDLE_BACK_MM = 30.0  # app.js: the needle is drawn this far back from the tip
TOL_MM = 1e-3  # float32 mesh matrices in the page


# --- pure parts ------------------------------------------------------------------------------
@pytest.mark.parametrize("angle_deg, azimuth_deg", [(0, 0), (30, 0), (60, 0), (30, 120)])
def test_pose_axis_is_r_of_q_applied_to_minus_z(angle_deg, azimuth_deg):
    s = NeedleScript(angle_deg, azimuth_deg)
    axis = frames.pose_axis(s.quaternion)
    np.testing.assert_allclose(axis, s.axis, atol=1e-12)
    assert math.degrees(math.acos(-axis[2])) == pytest.approx(angle_deg)
    assert frames.pose_axis((0, 0, 0, 1)) == [0.0, 0.0, -1.0]  # identity: straight down (msgs_schema/topics.py)
    np.testing.assert_allclose(frames.pose_axis([2 * c for c in s.quaternion]), s.axis, atol=1e-12)  # not unit: normalised


def test_track_memory_keeps_the_deepest_insertion_until_withdrawn():
    t = frames.TrackMemory()
    rec = {"inserted": True, "entry_m": [0.0, 0.0, 0.0], "insertion_m": 2e-3}
    assert t.update(dict(rec))["deepest_m"] == 2e-3
    assert t.update(dict(rec, insertion_m=1e-3))["deepest_m"] == 2e-3  # retracting inside the track: still 2 mm
    assert t.update(dict(rec, entry_m=[1e-3, 0.0, 0.0], insertion_m=0.5e-3))["deepest_m"] == 0.5e-3  # a new entry
    assert t.update(dict(rec, inserted=False, insertion_m=0.0))["deepest_m"] == 0.0  # withdrawn: no track
    assert t.update(dict(rec, insertion_m=0.3e-3))["deepest_m"] == 0.3e-3


def test_needle_state_round_trip_and_gauge():
    from skin_sim_msgs.msg import NeedleState

    st = NeedleScript(60.0).state(2.0)
    got = frames.read_needle(fill_needle(NeedleState(), st, 123))
    for k, v in got.items():
        np.testing.assert_allclose(v, st[k], err_msg=k)
    assert frames.needle_gauge(0.819e-3) == 21 and frames.needle_gauge(0.6e-3) is None


def test_scripted_insertion_punctures_at_the_crossings():
    """The fake's own contract (the test below leans on it): flat interfaces, crossings at depth / cos(angle)."""
    s = NeedleScript(60.0, depth_m=8e-3)
    rest = np.concatenate([[0.0], np.cumsum(s.thickness_m)])
    np.testing.assert_allclose(s.crossing_m, rest / 0.5)
    ks = [s.state(t)["ruptured_layers"] for t in np.linspace(0, s.period_s / 2, 400)]
    assert ks == sorted(ks) and ks[-1] == 3


# --- bag ---------------------------------------------------------------------------------------
def _rosbags_needle():
    """A zero ``rosbags`` NeedleState (``bags.io.new_message`` has no default for its fixed-size arrays)."""
    from rosbags.interfaces import Nodetype

    from msgs_schema.topics import TOPICS
    from skin_sim_node.bags.io import new_message, typestore

    assert register_needle_type(None)
    name, ts = TOPICS["needle"].type, typestore()
    kw = {}
    for field, (kind, arg) in ts.fielddefs[name][1]:
        if kind == Nodetype.ARRAY:
            kw[field] = np.zeros(arg[1])
        elif kind == Nodetype.SEQUENCE:
            kw[field] = np.zeros(0)
        elif kind == Nodetype.NAME:
            kw[field] = new_message(arg)
        else:
            kw[field] = False if arg[0] == "bool" else (0.0 if arg[0].startswith("float") else 0)
    return ts.types[name](**kw)


def _write_needle_bag(path, script: NeedleScript, rate_hz: float = 50.0) -> None:
    from msgs_schema import convert as cv
    from msgs_schema.topics import TOPICS
    from skin_sim_node.bags.io import BagWriter, new_message, qos_profiles

    assert register_needle_type(None)
    with BagWriter(path) as w:
        for i in range(int(script.period_s * rate_hz)):
            t = i / rate_hz
            t_ns = 1_000_000_000 + int(t * 1e9)
            st = script.state(t)
            out = {
                "tool_pose": cv.fill_pose(new_message(TOPICS["tool_pose"].type), t_ns, "tissue", st["tip_m"], st["quaternion"]),
                "tool_wrench": cv.fill_wrench(new_message(TOPICS["tool_wrench"].type), t_ns, "tissue", st["force_n"]),
                "needle": fill_needle(_rosbags_needle(), st, t_ns),
            }
            if i % 10 == 0:
                g = script.grid(st, 24, 24, (0.12, 0.12))
                img = cv.fill_image(new_message(TOPICS["layer_heights"].type), t_ns, "tissue", g)
                img.data = np.frombuffer(img.data, np.uint8)  # rosbags serialises uint8[] from an array
                out["layer_heights"] = img
            for k, m in out.items():
                w.write("/" + TOPICS[k].name, TOPICS[k].type, t_ns, m, qos_profiles(k))


@pytest.fixture(scope="module")
def needle_bag(tmp_path_factory):
    path = tmp_path_factory.mktemp("needle_bag") / "bag"
    script = NeedleScript(60.0, depth_m=4.0e-3)
    _write_needle_bag(path, script)
    return path, script


def test_bag_carries_the_needle_and_its_deepest_insertion(needle_bag):
    path, script = needle_bag
    d = BagData([path])
    assert len(d.needles) > 0 and d.pose_q.shape == (len(d.pose_t), 4)
    assert BagSource([path]).info()["tool_shape"] == "needle"
    ramp_s = (script.depth_m - script.start_m) / script.speed_m_s
    h = d.header_at(ramp_s + script.hold_s + 0.5)  # backing out: the track still reaches the deepest insertion
    nd = h["needle"]
    assert nd["inserted"] and nd["insertion_m"] < script.depth_m - 0.5e-3
    assert nd["deepest_m"] == pytest.approx(script.depth_m) and nd["ruptured_layers"] == 3
    np.testing.assert_allclose(frames.pose_axis(h["tool_q"]), script.axis, atol=1e-9)
    assert d.header_at(script.period_s - 0.1)["needle"]["deepest_m"] == 0.0  # withdrawn: no track


# --- the page ----------------------------------------------------------------------------------
def _drawn(p_m, zs: float) -> np.ndarray:
    """app.js drawPt: m in the tissue frame -> drawn mm (depth below the rest surface times the z scale)."""
    x, y, z = (1e3 * c for c in p_m)
    return np.array([x, y, z * zs if z < 0 else z])


def _check_scene(got: dict, script: NeedleScript) -> dict:
    """The drawn needle, track and punctured segments against the scripted geometry; returns the page's record."""
    rec, zs = got["rec"], got["zscale"]
    assert got["visible"] and rec is not None
    axis, entry = np.array(script.axis), np.zeros(3)
    np.testing.assert_allclose(rec["axis"], axis, atol=1e-9)
    assert rec["angleDeg"] == pytest.approx(script.angle_deg)
    # the needle: from the tip back 30 mm along the axis, split at the rest surface, its outer diameter
    tip = np.array(rec["tipM"])
    parts = [np.array(p) for p in got["needle"] if p is not None]
    assert parts, got
    np.testing.assert_allclose(parts[0][0], _drawn(tip, zs), atol=TOL_MM)
    np.testing.assert_allclose(parts[-1][1], _drawn(tip - axis * NEEDLE_BACK_MM * 1e-3, zs), atol=TOL_MM)
    assert got["radiusMm"] == pytest.approx(0.819 / 2, rel=1e-6)  # needle.outer_diameter_m's default (21 G)
    # the track: entry to the deepest insertion along the axis
    deepest = rec["track"]["lengthM"]
    assert 0 < deepest <= script.depth_m + 1e-12
    np.testing.assert_allclose(got["track"][0], _drawn(entry, zs), atol=TOL_MM)
    np.testing.assert_allclose(got["track"][1], _drawn(entry + axis * deepest, zs), atol=TOL_MM)
    # punctured layers: as the script ruptures them, each from its top's crossing to the next (or the deepest point)
    cr = script.crossing_m
    k = sum(1 for i in range(3) if deepest > cr[i] + FAKE_RUPTURE_DIMPLE_M[i] - 1e-12)
    segs = got["segments"]
    for i in range(3):
        if i < k:
            s1 = min(cr[i + 1], deepest)
            np.testing.assert_allclose(segs[i][0], _drawn(entry + axis * cr[i], zs), atol=TOL_MM)
            np.testing.assert_allclose(segs[i][1], _drawn(entry + axis * s1, zs), atol=TOL_MM)
        else:
            assert segs[i] is None, (i, k, segs)  # an intact layer ahead: not coloured
    # in the layer colours of the page's legend (app.js LAYER_RGB, sRGB)
    want = ["{:02x}{:02x}{:02x}".format(*(round(255 * c) for c in rgb)) for rgb in frames_layer_rgb()]
    assert got["segmentColours"] == want
    return rec


def frames_layer_rgb():
    from msgs_schema.convert import LAYER_RGBA

    return [rgba[:3] for rgba in LAYER_RGBA]


def _served(paths):
    """A view server playing the bags ``paths`` (its player thread running); stopped and closed on exit."""
    return served(BagSource(paths), 120.0)


@needs_browser
def test_bag_page_draws_the_needle_track_and_punctured_layers(needle_bag):
    from skin_sim_node.view.browser import Browser

    path, script = needle_bag
    with _served([path]) as srv, Browser(srv.url) as b:
        b.wait_for("window.skinView && window.skinView.gridFrames > 0", 60, "the first grid")
        ramp_s = (script.depth_m - script.start_m) / script.speed_m_s
        for t_s, k in ((ramp_s * 0.62, None), (ramp_s + script.hold_s / 2, 3)):
            b.evaluate(f"fetch('/api/seek', {{method: 'POST', body: JSON.stringify({{t_s: {t_s}}})}}).then(r => r.json())")
            b.wait_for(f"Math.abs(window.skinView.t_s - {t_s}) < 1e-6", 20, f"the frame at {t_s:.3f} s")
            rec = _check_scene(b.evaluate("window.skinViewNeedle()"), script)
            if k is not None:
                assert len(rec["segments"]) == k
        text = b.evaluate("document.getElementById('needle-info').textContent")
        assert "21 G" in text and "punctured 3 of 3" in text and "insertion" in text and "cutting" in text, text
        assert b.evaluate("window.skinView.toolShape") == "needle"
        # the z scale bends the drawing below the surface: the track follows it
        b.evaluate("(() => { const z = document.getElementById('zscale'); z.value = '1'; "
                   "z.dispatchEvent(new Event('change')); return true; })()")  # fmt: skip
        got = b.evaluate("window.skinViewNeedle()")
        assert got["zscale"] == 1
        _check_scene(got, script)


@needs_browser
def test_bag_without_a_needle_draws_none():
    from skin_sim_node.view.browser import Browser

    data = Path(__file__).resolve().parent / "data" / "press_all_layers"  # the flat punch's golden bag (test_view.py)
    with _served([data / "input", data / "expected"]) as srv, Browser(srv.url) as b:
        b.wait_for("window.skinView && window.skinView.gridFrames > 0", 60, "the first grid")
        n = b.evaluate("window.skinView.frames")
        b.wait_for(f"window.skinView.renderedFrames >= {n}", 20, "a render")
        got = b.evaluate("window.skinViewNeedle()")
        assert got["visible"] is False and got["rec"] is None
        assert b.evaluate("window.skinView.toolShape") == "cylinder"
        assert b.evaluate("getComputedStyle(document.getElementById('needle-info')).display") == "none"


@pytest.mark.ros
@needs_browser
def test_live_page_draws_an_oblique_needle_from_its_topics(ros_domain, tmp_path):
    """A real NeedleState + PoseStamped publisher (the scripted needle at 30 deg) and ``skin-sim view`` over DDS."""
    from skin_sim_node.scenes import REPO, Proc, Scene
    from skin_sim_node.view.browser import Browser

    ns = "/view_needle"
    script = NeedleScript(30.0)
    with Scene(tmp_path / "logs") as scene:
        argv = [sys.executable, "-m", "skin_sim_node.view.needle_fake", "--namespace", ns, "--angle-deg", "30"]
        log = tmp_path / "logs" / "needle_fake.log"
        with open(log, "w") as fh:
            popen = subprocess.Popen(argv, stdout=fh, stderr=subprocess.STDOUT, env=scene.env, cwd=REPO)
        scene.procs.append(Proc("needle_fake", argv, popen, log))
        view = scene.start("view", "view", "--namespace", ns, "--port", "0")
        scene.wait_for_log(view, "skin-sim view: http", timeout_s=60)
        url = view.log().split("skin-sim view: ", 1)[1].split()[0]
        with Browser(url) as b:
            b.wait_for("window.skinView && window.skinView.gridFrames > 0", 60, "tissue grids on the page")
            seen = set()
            for k in (1, 3):  # while puncturing, and with every layer punctured (a loop of the script: 7.5 s)
                cond = f"window.skinView.needle && window.skinView.needle.segments.length >= {k}"
                b.hold_when(cond, 60, f"{k} punctured layers")  # the page keeps this frame while it is read
                got = b.evaluate("window.skinViewNeedle()")
                b.release()
                seen.add(len(_check_scene(got, script)["segments"]))
            assert max(seen) == 3
            assert "live " + ns == b.evaluate("document.getElementById('mode').textContent")
            text = b.evaluate("document.getElementById('needle-info').textContent")
            assert "30.0\u00b0 from vertical" in text and "punctured" in text and "friction" in text, text
