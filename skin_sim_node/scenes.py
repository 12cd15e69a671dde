"""Scenes: several skin-sim executables started as separate OS processes with one command.

Every process is ``python -m skin_sim_node.cli <command> ...`` with a shared environment,
so the scene works wherever this interpreter has rclpy. Isolation: a scene keeps the
caller's ``ROS_DOMAIN_ID`` if set, otherwise it picks one; discovery is localhost-only
unless the caller set ``ROS_AUTOMATIC_DISCOVERY_RANGE``.
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from msgs_schema.spec import ConfigError

REPO = Path(__file__).resolve().parents[1]


class StartRefusedError(ConfigError, RuntimeError):
    """A scene's process refused its parameters at start (a :class:`ConfigError`: the command ends with its one line;
    a ``RuntimeError`` as every other failed start)."""


DEFAULT_PARAMS = Path(__file__).resolve().parent / "config" / "default.yaml"
"""The node parameter file of the scenes: the packaged copy of ``config/default.yaml`` (found in an install too)."""


def pick_domain_id() -> int:
    """A random DDS domain id, from ``SKIN_SIM_DOMAIN_RANGE`` ("lo-hi") if set, else 1-101.

    Ids above 101 limit the participants per domain on Linux (ROS 2 docs). Parallel runs on one
    host (several CI jobs, several developers) give each a disjoint range so they never meet.
    """
    lo, hi = 1, 101
    spec = os.environ.get("SKIN_SIM_DOMAIN_RANGE", "").strip()
    if spec:
        try:
            lo, hi = (int(v) for v in spec.split("-"))
        except ValueError:
            raise ValueError(f"SKIN_SIM_DOMAIN_RANGE must look like '20-39', got {spec!r}") from None
        if not 0 <= lo <= hi <= 232:
            raise ValueError(f"SKIN_SIM_DOMAIN_RANGE {spec!r} is outside 0-232")
    return random.SystemRandom().randint(lo, hi)


def isolated_env(domain_id: int | None = None, log_dir: Path | None = None) -> dict[str, str]:
    """Environment for a scene: its own DDS domain, localhost discovery, tidy ROS logs."""
    env = dict(os.environ)
    if domain_id is not None:
        env["ROS_DOMAIN_ID"] = str(domain_id)
    elif "ROS_DOMAIN_ID" not in env:
        env["ROS_DOMAIN_ID"] = str(pick_domain_id())
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env.pop("ROS_LOCALHOST_ONLY", None)  # deprecated in Jazzy; it overrides the range
    if log_dir is not None:
        env["ROS_LOG_DIR"] = str(log_dir)
    env["PYTHONUNBUFFERED"] = "1"
    return env


STOP_TIMEOUT_S = 10.0
"""What every skin-sim process is given to exit after SIGINT or SIGTERM before a scene kills it. Measured with two
busy processes beside it (tests/test_shutdown.py): node 0.7-0.8 s, bridge and device 0.2-0.5 s."""


@dataclass
class Proc:
    """One started process of a scene: name, command line, ``Popen`` and log file."""

    name: str
    argv: list[str]
    popen: subprocess.Popen
    log_path: Path

    def log(self) -> str:
        """The process's output so far (empty before the log file exists)."""
        return self.log_path.read_text(errors="replace") if self.log_path.exists() else ""


@dataclass
class Scene:
    """Start, watch and stop a set of processes. Use as a context manager."""

    log_dir: Path
    domain_id: int | None = None
    procs: list[Proc] = field(default_factory=list)

    def __post_init__(self):
        self.log_dir = Path(self.log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.env = isolated_env(self.domain_id, self.log_dir / "ros")

    def start(self, name: str, command: str, *args: str) -> Proc:
        """Start ``python -m skin_sim_node.cli COMMAND ARGS`` as process ``name``, output to ``LOG_DIR/name.log``."""
        argv = [sys.executable, "-m", "skin_sim_node.cli", command, *args]
        log_path = self.log_dir / f"{name}.log"
        fh = open(log_path, "w")
        popen = subprocess.Popen(argv, stdout=fh, stderr=subprocess.STDOUT, env=self.env, cwd=REPO)
        proc = Proc(name, argv, popen, log_path)
        self.procs.append(proc)
        return proc

    def node(self, *extra: str, params: Path = DEFAULT_PARAMS, options: tuple[str, ...] = ()) -> Proc:
        """Start ``skin_sim_node`` with the parameter file ``params``, the node command's ``options`` (before its ROS
        arguments, e.g. ``("--journal", path)``) and extra ``--ros-args``.

        Raises
        ------
        ConfigError
            ``params`` has an unknown name or a bad value (checked against the contract before any process starts).
        """
        from msgs_schema.parameters import validate_parameters

        from .model.config import load_yaml

        validate_parameters(load_yaml(params))  # one line through the command's error, not a node's failed start
        return self.start("skin_sim_node", "node", *options, "--ros-args", "--params-file", str(params), *extra)

    def wait_for_log(self, proc: Proc, text: str, timeout_s: float = 60.0) -> None:
        """Wait until ``text`` appears in ``proc``'s log.

        Raises
        ------
        StartRefusedError
            The process refused its parameters (exit 2 with one ``error:`` line): that line.
        RuntimeError
            The process exited first (with the log's tail).
        TimeoutError
            Not within ``timeout_s``.
        """
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if text in proc.log():
                return
            if proc.popen.poll() is not None:
                last = (proc.log().strip().splitlines() or [""])[-1]
                if proc.popen.returncode == 2 and last.startswith("error: "):  # a refused parameter: its one line
                    raise StartRefusedError(f"{proc.name}: {last[len('error: ') :]}")
                raise RuntimeError(f"{proc.name} exited with {proc.popen.returncode}:\n{proc.log()[-3000:]}")
            time.sleep(0.05)
        raise TimeoutError(f"{proc.name} did not log {text!r} within {timeout_s} s:\n{proc.log()[-3000:]}")

    def stop(self, proc: Proc, timeout_s: float = STOP_TIMEOUT_S) -> int:
        """SIGTERM ``proc`` and wait up to ``timeout_s`` for it; SIGKILL it past that (its code is then -9)."""
        if proc.popen.poll() is None:
            proc.popen.send_signal(signal.SIGTERM)
            try:
                proc.popen.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                proc.popen.kill()
                proc.popen.wait()
        return proc.popen.returncode

    def stop_all(self) -> dict[str, int]:
        """Stop every process, last started first: ``{name: exit code}``."""
        return {p.name: self.stop(p) for p in reversed(self.procs)}

    def __enter__(self) -> Scene:
        return self

    def __exit__(self, *exc) -> None:
        self.stop_all()


SCENES = {
    "demo-device": "skin_sim_node + device bridge + simulated Touch (CRTK) following a hand path",
    "demo-mock": "skin_sim_node + mock tool publisher",
}


def run_scene(kind: str, path: str, log_dir: Path, duration_s: float | None) -> int:
    """Start a scene, wait until its tool source finishes (or ``duration_s``), stop it."""
    with Scene(log_dir) as scene:
        node = scene.node()
        scene.wait_for_log(node, "live:")
        if kind == "demo-device":
            scene.start("bridge", "bridge")
            source = scene.start("device", "device", "--hand-path", path)
        else:
            source = scene.start("mock_tool", "mock-tool", "--trajectory", path)
        print(f"scene {kind} running (ROS_DOMAIN_ID={scene.env['ROS_DOMAIN_ID']}, logs in {log_dir})", flush=True)
        try:
            source.popen.wait(timeout=duration_s)
        except subprocess.TimeoutExpired:
            pass
        except KeyboardInterrupt:
            pass
        codes = scene.stop_all()
    print("exit codes:", codes)
    return 0 if all(c in (0, -signal.SIGTERM) for c in codes.values()) else 1


def main(argv=None) -> int:
    """``skin-sim scene KIND``: start a scene's processes, wait for the tool to finish (or ``--duration-s``), stop them."""
    ap = argparse.ArgumentParser(prog="skin-sim scene", description="Start a scene as separate processes.")
    ap.add_argument("kind", choices=sorted(SCENES), help="; ".join(f"{k}: {v}" for k, v in SCENES.items()))
    ap.add_argument("--path", default="press_hold_release", help="hand path / trajectory name")
    ap.add_argument("--duration-s", type=float, default=None, help="stop after this long (default: when the tool is done)")
    ap.add_argument("--log-dir", type=Path, default=Path("out/scene"))
    args = ap.parse_args(argv)
    return run_scene(args.kind, args.path, args.log_dir, args.duration_s)


if __name__ == "__main__":
    raise SystemExit(main())
