"""What a command says at start and on a mistake: the node's first line, and one-line errors with a suggestion.

Used by :mod:`skin_sim_node.cli` (before a subcommand runs) and by the node's start-up log.
"""

from __future__ import annotations

import argparse
import difflib
import re
from pathlib import Path

from msgs_schema.spec import ConfigError, read_yaml


def params_files(ros_args) -> list[str]:
    """The ``--params-file PATH`` values among ROS arguments (in order)."""
    args = list(ros_args or [])
    return [args[i + 1] for i, a in enumerate(args[:-1]) if a == "--params-file"]


def key_matches(key: str, node_fqn: str) -> bool:
    """Whether a parameter-file key names the node ``node_fqn`` as rcl reads it: the key is a fully qualified node
    name (``skin_sim_node`` is ``/skin_sim_node``) where ``*`` is one name token and ``**`` any number of them,
    none included (``/**/skin_sim_node`` matches ``/skin_sim_node`` and ``/s1/skin_sim_node``)."""
    parts = []
    for tok in key.strip("/").split("/"):
        if tok == "**":
            parts.append("(?:/[^/]+)*")
        elif tok == "*":
            parts.append("/[^/]+")
        else:
            parts.append("/" + re.escape(tok))
    return re.fullmatch("".join(parts), node_fqn) is not None


def applies_to(params_file: str, node_fqn: str) -> bool | None:
    """Whether a ``ros__parameters`` file has an entry for the node ``node_fqn`` (None: the file cannot be read).

    A node started in a namespace does not match a bare ``skin_sim_node:`` key (:func:`key_matches`).
    """
    import yaml

    try:
        keys = list((yaml.safe_load(Path(params_file).read_text()) or {}).keys())
    except (OSError, yaml.YAMLError, AttributeError):
        return None
    return any(key_matches(str(key), node_fqn) for key in keys)


def start_line(flat: dict, ros_args, node_fqn: str | None = None) -> str:
    """The node's first log line: tissue form, preset file(s) and tool.

    Parameters
    ----------
    flat : dict
        The node's parameters by full name (``tissue.form``, ``tissue.tool.shape``, ``tissue.tool.radius_m``).
    ros_args : list of str
        The node's ROS arguments (``--params-file`` values are the presets).
    node_fqn : str, optional
        The node's fully qualified name: a preset file without an entry for it is named as not applied.

    Returns
    -------
    str
        E.g. ``starting: tissue form 'paper', preset config/paper.yaml, tool flat punch r = 2.50 mm``.
    """
    files = params_files(ros_args)
    named = []
    for f in files:
        hit = applies_to(f, node_fqn) if node_fqn else True
        named.append(f if hit is not False else f"{f} (NOT applied: it has no entry for {node_fqn}; key it '/**/skin_sim_node:')")
    preset = "preset " + ", ".join(named) if files else "no preset file (the schema's defaults; see --params-file)"
    shape = str(flat.get("tissue.tool.shape", "?"))
    tool = {"flat": "flat punch", "sphere": "sphere"}.get(shape, shape)
    if shape == "needle":
        d = float(flat.get("tissue.needle.outer_diameter_m", float("nan")))
        lube = "lubricated" if flat.get("tissue.needle.lubricated", True) else "dry"
        size = f"outer diameter {d * 1e3:.3f} mm ({lube}); its axis from the pose's orientation"
    else:
        size = f"r = {float(flat.get('tissue.tool.radius_m', float('nan'))) * 1e3:.2f} mm"
    return f"starting: tissue form '{flat.get('tissue.form', '?')}', {preset}, tool {tool} {size}"


def node_argument_error(rest: list[str]) -> str | None:
    """A mistake in ``skin-sim node`` arguments that rclpy would ignore silently, as one line (None: none).

    ``--params-file`` (or ``-p``) before ``--ros-args`` is not a ROS argument and the node would run its
    defaults; a ``--params-file`` that does not exist would end in a traceback.
    """
    ros = rest.index("--ros-args") if "--ros-args" in rest else len(rest)
    for i, a in enumerate(rest[:ros]):
        if a in ("--params-file", "-p", "--param", "-r", "--remap"):
            val = rest[i + 1] if i + 1 < len(rest) else "..."
            return f"{a} {val} is a ROS argument and goes after --ros-args: skin-sim node --ros-args {a} {val}"
    for path in params_files(rest[ros:]):
        if not Path(path).is_file():
            return f"--params-file {path}: no such file"
        try:  # rcl's own parse error is a C log line and more: say it in one line first
            read_yaml(path)
        except ConfigError as exc:
            return f"--params-file {exc}"
    return None


def suggest(word: str, choices) -> str:
    """``" (did you mean 'x'?)"`` for the closest of ``choices``, or an empty string."""
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def install_option_suggestions() -> None:
    """Make every argparse parser of this process answer a mistake with one line, suggesting the closest option.

    ``--stabilizer`` then reads ``skin-sim bridge: error: unrecognized arguments: --stabilizer passivity (did you
    mean '--stabiliser'?); skin-sim bridge --help shows the usage``, without the usage block above it.
    """
    if getattr(argparse.ArgumentParser.error, "_suggests", False):
        return

    def error(self, message):
        if message.startswith("unrecognized arguments: "):
            opts = [o for a in self._actions for o in a.option_strings if o.startswith("--")]
            words = [w.split("=", 1)[0] for w in message[len("unrecognized arguments: ") :].split() if w.startswith("--")]
            message += "".join(suggest(w, opts) for w in words)
        self.exit(2, f"{self.prog}: error: {message}; {self.prog} --help shows the usage\n")

    # a deliberate patch of the class (every parser of the process), marked so that it is made once: mypy types
    # neither a function's own attribute nor an assignment to a method
    error._suggests = True  # type: ignore[attr-defined]
    argparse.ArgumentParser.error = error  # type: ignore[method-assign]
