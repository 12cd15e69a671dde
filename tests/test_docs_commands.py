"""Every ``skin-sim`` command quoted in README.md and docs/*.md still exists, with every option it is quoted with
(issue 29 item 3: a check that each quoted command still exists). Code only: fenced blocks and inline code spans."""

from __future__ import annotations

import contextlib
import importlib
import io
import re
from pathlib import Path

import pytest

from skin_sim_node.cli import CHART_TARGETS, COMMANDS

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
COMMAND = re.compile(r"skin-sim ([a-z][a-z0-9-]*)([^`#|;\n]*)")
OPTION = re.compile(r"--[a-z][a-z0-9-]*")


def code_of(text: str) -> list[str]:
    """The page's code: each line of a fenced block, and each inline code span elsewhere."""
    out, fenced = [], False
    for line in text.splitlines():
        if line.lstrip().startswith("```"):
            fenced = not fenced
        elif fenced:
            out.append(line.split("#", 1)[0])
        else:
            out += re.findall(r"`([^`]+)`", line)
    return out


def quoted() -> dict[tuple[str, ...], dict]:
    """``(command,)`` or ``("chart", target)`` -> the options it is quoted with and the pages that quote it."""
    found: dict[tuple[str, ...], dict] = {}
    for page in PAGES:
        for code in code_of(page.read_text()):
            for m in COMMAND.finditer(code):
                if m.group(1) not in COMMANDS and m.group(1) != "chart" and ":" in m.group(2):
                    continue  # a line a command printed (`skin-sim model micro-benchmark: ...`), not a command
                words = m.group(2).split()
                ros = words.index("--ros-args") if "--ros-args" in words else len(words)  # ROS arguments are rcl's
                key: tuple[str, ...] = (m.group(1),)
                if m.group(1) == "chart" and words and not words[0].startswith("-"):
                    key = ("chart", words[0])
                entry = found.setdefault(key, {"options": set(), "pages": set()})
                entry["options"].update(w.split("=")[0] for w in words[:ros] if OPTION.fullmatch(w.split("=")[0]))
                entry["pages"].add(page.name)
    return found


QUOTED = quoted()


def test_the_pages_quote_commands():
    assert ("demo",) in QUOTED and ("bridge",) in QUOTED and ("chart", "validation") in QUOTED
    assert "--device" in QUOTED[("bridge",)]["options"]  # the README's real-device line


def help_text(key: tuple[str, ...]) -> str:
    """The command's ``--help`` as printed, in this process (argparse prints and exits)."""
    module = CHART_TARGETS[key[1]][0] if key[0] == "chart" else COMMANDS[key[0]][0]
    main = importlib.import_module(module).main
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pytest.raises(SystemExit):
        main(["--help"])
    return buf.getvalue()


@pytest.mark.parametrize("key", sorted(QUOTED), ids=" ".join)
def test_quoted_command_and_options_exist(key):
    where = ", ".join(sorted(QUOTED[key]["pages"]))
    if key[0] == "chart":
        assert key[1] in CHART_TARGETS, f"skin-sim chart {key[1]} (quoted in {where}) is no chart target"
    else:
        assert key[0] in COMMANDS, f"skin-sim {key[0]} (quoted in {where}) is no command"
    text = help_text(key)
    chart_own = {"--docs"} if key[0] == "chart" else set()  # skin-sim chart's own option, before the target's
    missing = sorted(o for o in QUOTED[key]["options"] - chart_own if not re.search(re.escape(o) + r"\b", text))
    assert not missing, f"skin-sim {' '.join(key)}: options quoted in {where} that --help does not list: {missing}"
