"""The bridge's PM QoS CPU latency request (``skin_sim_node.ros_util.hold_cpu_latency``, ``cpu_latency_us``), on a
stand-in file for ``/dev/cpu_dma_latency``: what it writes, that one process holds one request (the lowest asked),
and the one-line reason when it cannot."""

from __future__ import annotations

import struct

import pytest

from skin_sim_node import ros_util
from skin_sim_node.device.bridge_params import BRIDGE_PARAMS, CPU_LATENCY_US


@pytest.fixture
def device(tmp_path, monkeypatch):
    path = tmp_path / "cpu_dma_latency"
    path.write_bytes(b"")
    monkeypatch.setattr(ros_util, "CPU_LATENCY_DEVICE", str(path))
    monkeypatch.setattr(ros_util, "_cpu_latency", None)
    return path


def test_the_request_is_a_native_s32_and_the_lowest_asked_is_held(device):
    assert ros_util.hold_cpu_latency(50) is None
    assert struct.unpack("i", device.read_bytes()) == (50,)
    held = ros_util._cpu_latency
    assert ros_util.hold_cpu_latency(80) is None and ros_util._cpu_latency == held  # a higher one changes nothing
    assert ros_util.hold_cpu_latency(0) is None and ros_util._cpu_latency[1] == 0
    assert device.read_bytes()[-4:] == struct.pack("i", 0)


def test_no_device_gives_a_reason_and_holds_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr(ros_util, "CPU_LATENCY_DEVICE", str(tmp_path / "absent"))
    monkeypatch.setattr(ros_util, "_cpu_latency", None)
    why = ros_util.hold_cpu_latency(0)
    assert why is not None and "not held" in why and "\n" not in why
    assert ros_util._cpu_latency is None


def test_the_bridge_parameter_defaults_to_the_cyclictest_request():
    spec = next(p for p in BRIDGE_PARAMS if p.name == "cpu_latency_us")
    assert spec.default == CPU_LATENCY_US == 0 and spec.lo == -1
