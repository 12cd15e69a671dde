"""The hands' contract (issue 32): names, topics and the one-tool default. No DDS."""

from __future__ import annotations

import pytest

from msgs_schema.parameters import check_hands, node_params_from_flat
from msgs_schema.spec import ConfigError
from msgs_schema.topics import HAND_TOPICS, TOPICS, hand_topic
from skin_sim_node.model import preset
from skin_sim_node.tools import CoupledTool, FlatPunch, make_tool, make_tools


def test_a_single_hand_keeps_the_single_tool_names_and_tool():
    for key in TOPICS:
        assert hand_topic(key, "") == TOPICS[key].name
    cfg = preset("default")
    (tool,) = make_tools([cfg])
    assert type(tool) is FlatPunch and type(make_tool(cfg)) is FlatPunch


def test_each_hand_has_its_own_tool_topics_and_shares_the_tissues():
    assert hand_topic("tool_pose", "left") == "left/tool/pose"
    assert hand_topic("needle", "right") == "right/" + TOPICS["needle"].name
    assert hand_topic("layer_heights", "left") == TOPICS["layer_heights"].name  # the tissue's, one per node
    assert hand_topic("diagnostics", "left") == TOPICS["diagnostics"].name
    assert set(HAND_TOPICS) <= set(TOPICS)
    tools = make_tools([preset("default"), preset("needle")])
    assert all(type(t) is CoupledTool for t in tools) and tools[0].skin is tools[1].skin


@pytest.mark.parametrize(
    ("first", "second", "why"),
    [
        ("left", "left", "different namespaces"),
        ("", "9hand", "one name token"),
        ("a/b", "", "one name token"),
        ("", "left hand", "one name token"),
    ],
)
def test_bad_hand_names_stop_with_one_line(first, second, why):
    with pytest.raises(ConfigError, match=why) as err:
        check_hands(first, second)
    assert "\n" not in str(err.value)
    with pytest.raises(ConfigError, match=why):
        node_params_from_flat({"hand_ns": first, "second_hand_ns": second})


def test_more_hands_than_the_limit_are_refused():
    from skin_sim_node.tools import MAX_HANDS, SharedSkin

    cfg = preset("default")
    with pytest.raises(ValueError, match=f"1 to {MAX_HANDS} tools"):
        SharedSkin([make_tool(cfg) for _ in range(MAX_HANDS + 1)])


def test_the_offline_check_uses_the_answers_a_reader_saw_for_the_last_second():
    from skin_sim_node.demo.hands import settled_stamps

    ms = 1_000_000
    assert settled_stamps([]) == ([], 0)
    every = [k * ms for k in range(100)]
    assert settled_stamps(every) == (every, 0)  # no gap: every answer
    gapped = every + [200 * ms + k * ms for k in range(2000)]  # a 101 ms gap, then 2 s of answers
    used, gaps = settled_stamps(gapped, gap_s=0.05, settle_s=1.0)
    assert gaps == 1 and used == every + [200 * ms + k * ms for k in range(1000, 2000)]
    late = [k * ms for k in range(1500)]  # the reader joined a press: its first second is not compared
    assert settled_stamps(late, settle_s=1.0, started_in_contact=True) == ([k * ms for k in range(1000, 1500)], 1)
