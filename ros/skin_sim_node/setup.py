"""The ament_python build of ``skin_sim_node`` (colcon-ros runs this ``setup.py``): the repository's packages, two
folders up, with the package data and the ``skin-sim`` entry point of ``pyproject.toml``.

``pip install`` of the repository (the README's path) reads ``pyproject.toml`` and never this file. Kept plain
(``setup.py`` only, no ``pyproject.toml`` here): colcon-python-setup-py reads the distribution's attributes back as
Python literals, which a ``pyproject.toml`` project's ``python_requires`` is not.
"""

import re
from pathlib import Path

from setuptools import find_packages, setup

HERE = Path(__file__).resolve().parent
ROOT = Path("..") / ".."  # relative, as setuptools wants package_dir
PYPROJECT = (HERE / ROOT / "pyproject.toml").read_text()
VERSION = re.search(r'^version = "([^"]+)"', PYPROJECT, re.M).group(1)  # tomllib is 3.11+; the project allows 3.10

setup(
    name="skin_sim_node",
    version=VERSION,
    description="Real-time layered skin haptic simulation server over ROS 2 (skin_sim_node, bridge, tools)",
    license="Apache-2.0",
    python_requires=">=3.10",
    package_dir={"": str(ROOT)},
    packages=find_packages(str(HERE / ROOT), include=["skin_sim_node*", "msgs_schema*"]),
    package_data={
        "skin_sim_node": ["fastdds_localhost_udp.xml", "config/*.yaml"],
        "skin_sim_node.view": ["static/*.html", "static/*.js", "static/vendor/*"],
    },
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/skin_sim_node"]),
        ("share/skin_sim_node", ["package.xml"]),
    ],
    entry_points={"console_scripts": ["skin-sim = skin_sim_node.cli:main"]},
    zip_safe=False,
)
