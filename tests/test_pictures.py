"""The pictures say what happened: the report's shading, the flat punch's note, the release trace's start."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from skin_sim_lab.viz.figures import press
from skin_sim_node.bags.inputs import InputOptions, read_inputs
from skin_sim_node.bags.offline import replay
from skin_sim_node.bags.plots import punch_face_gap_m
from skin_sim_node.bags.report import _shaded_ms, depth_layer
from skin_sim_node.model import SkinModel, preset

DATA = Path(__file__).parent / "data"


def test_report_shading_follows_the_tool_depth_not_the_layers_acting():
    """Layered form: all 3 layers act from first touch; the shading must start at the epidermis."""
    res = replay(read_inputs(DATA / "press_all_layers" / "input", InputOptions()), grid_rate_hz=0)
    layer = depth_layer(res)
    touching = np.flatnonzero(res.depth_m > 0)
    assert res.n_affected[touching[0]] == 3  # what the old shading used: "fat" from the first touch
    assert layer[touching[0]] == 0 and layer[res.peak_index] == 2 and layer[0] == -1
    assert set(np.unique(layer)) == {-1, 0, 1, 2}
    # the legend tells each band's time, the epidermis's few ms included; the bands and the lifted time fill the run
    t = (res.stamps_ns - res.stamps_ns[0]) * 1e-9
    shaded = [_shaded_ms(t, layer == li) for li in (-1, 0, 1, 2)]
    assert all(ms > 0 for ms in shaded) and sum(shaded) == pytest.approx(1e3 * t[-1])


def test_flat_punch_gap_is_measured_where_the_figure_notes_it():
    model = SkinModel(preset("default"))
    press(model, 0.0, 0.0, 3e-3)
    gap = punch_face_gap_m(model, 0.0, 0.0, -3e-3)
    assert 0.1e-3 < gap < 3e-3  # the smooth field lies above the punch's face at its edge: the figure says by how much
