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
