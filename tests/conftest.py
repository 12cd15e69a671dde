import os
import threading
from contextlib import contextmanager

import numpy as np
import pytest

from skin_sim_node.model import SkinModel, preset


@pytest.fixture(scope="session")
def default_cfg():
    return preset("default")


@pytest.fixture(scope="session")
def paper_cfg():
    return preset("paper")


@pytest.fixture
def model(default_cfg):
    return SkinModel(default_cfg)


def kernel(fn, compiled):
    """The numba kernel compiled, or its pure-Python body."""
    return fn if compiled else fn.py_func


@pytest.fixture(params=[True, False], ids=["njit", "py_func"])
def compiled(request):
    return request.param


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture(scope="module")
def ros_domain():
    """This test module's own DDS domain with localhost-only discovery, so parallel runs never meet."""
    from skin_sim_node.scenes import pick_domain_id

    keys = ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY")
    saved = {k: os.environ.get(k) for k in keys}
    os.environ["ROS_DOMAIN_ID"] = str(pick_domain_id())
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.pop("ROS_LOCALHOST_ONLY", None)  # deprecated in Jazzy; it overrides the range
    yield int(os.environ["ROS_DOMAIN_ID"])
    for k, v in saved.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


@contextmanager
def node_in_process(**params):
    """The node class in this process with rclpy, in a context of its own, its clock thread stopped (the test ticks it)
    and no SCHED_FIFO (``rt_priority`` 0: it would be the whole pytest run's). ``params``: the node's parameter
    overrides."""
    rclpy = pytest.importorskip("rclpy")
    from rclpy.parameter import Parameter

    from skin_sim_node.server.node import SkinSimNode

    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    node = None
    try:
        overrides = [Parameter(k, value=v) for k, v in {**params, "rt_priority": 0}.items()]
        node = SkinSimNode(context=ctx, parameter_overrides=overrides)
        node._loop.stop()
        assert os.sched_getscheduler(0) == os.SCHED_OTHER  # the pytest process keeps normal scheduling
        yield node
    finally:
        if node is not None:
            node.stop()
            node.destroy_node()
        rclpy.shutdown(context=ctx)


@contextmanager
def served(src, duration_s: float = 180.0):
    """A view server for the source ``src`` (a bag or live source) with its player thread running, yielding the server;
    on exit the source stops, its thread is joined and the server closed."""
    from skin_sim_node.view.server import ViewServer

    srv = ViewServer(src, port=0).start()
    t = threading.Thread(target=src.run, args=(srv, duration_s), daemon=True)
    t.start()
    try:
        yield srv
    finally:
        src.stop()
        t.join(timeout=5)
        srv.close()
