"""What an install gets: the server path without the lab extra, and the presets in a non-editable install."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

LAB_ONLY = ("matplotlib", "skfem", "tqdm", "psutil")
"""The `lab` extra's import names (pyproject.toml): figures, FEM references, progress bars, process meters."""

SERVER_MODULES = (
    "skin_sim_node.server.node",
    "skin_sim_node.server.display",
    "skin_sim_node.device.bridge",
    "skin_sim_node.device.sim_device",
    "skin_sim_node.device.mock_tool",
    "skin_sim_node.session",
    "skin_sim_node.model",
    "skin_sim_node.bags.record",
    "skin_sim_node.bags.compare",
    "skin_sim_node.bags.offline",
    "skin_sim_node.bags.live",
    "skin_sim_node.bags.replay",
    "skin_sim_node.scenes",
    "skin_sim_node.cli",
)
"""What ``skin-sim node``, ``bridge``, ``device``, ``mock-tool``, ``scene``, ``record`` and ``compare`` import, and the
offline and live replay engines (``skin_sim_node.bags.replay`` itself still imports the report's matplotlib)."""

_BLOCKER = """
import importlib, sys
BLOCKED = {blocked!r}
class Blocked:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ImportError(f"{{name}} is blocked (the lab extra is not installed)")
        return None
sys.meta_path.insert(0, Blocked())
for lab in BLOCKED:
    try:
        importlib.import_module(lab)
    except ImportError:
        pass
    else:
        raise SystemExit(f"the blocker let {{lab}} through")
for mod in {modules!r}:
    importlib.import_module(mod)
print("imported", len({modules!r}), "modules; loaded lab modules:", sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED))
"""


def _run(code: str, cwd: Path, pythonpath: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(pythonpath))
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def test_server_modules_import_without_the_lab_extra(tmp_path):
    r = _run(_BLOCKER.format(blocked=LAB_ONLY, modules=SERVER_MODULES), tmp_path, ROOT)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.strip() == f"imported {len(SERVER_MODULES)} modules; loaded lab modules: []", r.stdout


def test_the_blocker_blocks(tmp_path):
    """The same subprocess fails for a module that needs the lab extra at import (the FEM reference)."""
    r = _run(_BLOCKER.format(blocked=LAB_ONLY, modules=("skin_sim_lab.validation.fem",)), tmp_path, ROOT)
    assert r.returncode != 0 and "skfem is blocked" in r.stderr, r.stderr[-3000:]


def test_a_non_editable_install_finds_the_presets(tmp_path):
    """``pip install --target`` of the package (not editable): ``preset()`` reads the packaged YAML, cwd elsewhere."""
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    for pkg in ("skin_sim_node", "msgs_schema", "skin_sim_lab"):
        shutil.copytree(ROOT / pkg, src / pkg, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc"))
    target = tmp_path / "site"
    pip = [
        sys.executable,
        "-m",
        "pip",
        "install",
        "--quiet",
        "--no-deps",
        "--no-build-isolation",
        "--target",
        str(target),
        str(src),
    ]
    r = subprocess.run(pip, capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    shipped = sorted(p.name for p in (target / "skin_sim_node" / "config").glob("*.yaml"))
    assert shipped == ["default.yaml", "isotropic.yaml", "needle.yaml", "paper.yaml", "two_hands.yaml"]
    assert (target / "skin_sim_lab" / "perf" / "bench_model.py").is_file()  # the lab ships beside the runtime
    code = (
        "import skin_sim_node, skin_sim_node.scenes as sc\n"
        "from skin_sim_node.model import preset\n"
        "from skin_sim_node.model.config import load_tissue_config, preset_path\n"
        "print(skin_sim_node.__file__)\n"
        "print(preset_path('default'), preset_path('paper'), sc.DEFAULT_PARAMS)\n"
        "print(preset('default').form, preset('paper').form, preset('default') == load_tissue_config(sc.DEFAULT_PARAMS))\n"
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    r = _run(code, elsewhere, target)
    assert r.returncode == 0, r.stderr[-3000:]
    where, paths, forms = r.stdout.strip().splitlines()
    assert Path(where).is_relative_to(target), f"imported {where}, not the install"
    assert all(Path(p).is_relative_to(target / "skin_sim_node" / "config") for p in paths.split()), paths
    assert forms == "layered paper True"


@pytest.mark.parametrize("name", ["default", "paper"])
def test_the_packaged_presets_are_the_top_level_files(name):
    from skin_sim_node.model.config import preset_path

    assert preset_path(name).read_text() == (ROOT / "config" / f"{name}.yaml").read_text()


def _workspace_copy(dest: Path) -> None:
    """The repository's tracked files (as a clone has them) under ``dest``."""
    files = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    for rel in filter(None, files.split("\0")):
        src = ROOT / rel
        if src.is_file():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)


@pytest.mark.slow
def test_colcon_builds_a_workspace_holding_the_repository(tmp_path):
    """Issue 29 item 8: ``colcon build`` in a workspace whose ``src`` holds this repository builds the message package
    (ament_cmake) and ``skin_sim_node`` (ament_python, ros/skin_sim_node), and the installed ``skin-sim --help`` runs
    from the install space (its own copy of the packages, not this checkout). About 45 s on 2 cores (the messages)."""
    colcon = Path(sys.executable).with_name("colcon")
    if not colcon.exists() or shutil.which("cmake") is None:
        pytest.skip("colcon (the test extra) or cmake is missing")
    ws = tmp_path / "ws"
    _workspace_copy(ws / "src" / "skin-sim")
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"  # the venv's python and colcon
    venv = Path(sys.prefix)
    if (venv / "share" / "rclpy").is_dir():  # ROS from PyPI wheels: the venv is the underlay (scripts/build_msgs.sh)
        env["AMENT_PREFIX_PATH"] = os.pathsep.join(filter(None, [str(venv), env.get("AMENT_PREFIX_PATH", "")]))
    build = subprocess.run(
        [str(colcon), "build", "--event-handlers", "console_direct-"],
        cwd=ws,
        env=env,
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    assert "Finished <<< skin_sim_msgs" in build.stdout and "Finished <<< skin_sim_node" in build.stdout, build.stdout
    install = ws / "install"
    assert (install / "skin_sim_node" / "share" / "ament_index" / "resource_index" / "packages" / "skin_sim_node").is_file()
    script = (
        f". {install / 'setup.sh'} && command -v skin-sim && skin-sim --help && "
        "python -c 'import skin_sim_node, skin_sim_msgs.msg; print(skin_sim_node.__file__); print(skin_sim_msgs.msg.__file__)'"
    )
    run = subprocess.run(["sh", "-c", script], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    lines = run.stdout.splitlines()
    assert lines[0] == str(install / "skin_sim_node" / "bin" / "skin-sim"), lines
    assert "usage: skin-sim COMMAND [args]" in run.stdout
    assert lines[-2].startswith(str(install / "skin_sim_node")) and lines[-1].startswith(str(install / "skin_sim_msgs")), lines
