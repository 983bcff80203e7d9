"""The docs stay honest where they state facts: every `quadtank` command and option
the parser knows is in docs/cli.md (and none it does not), every key the interface
binds is in docs/keys.md under its screen or window, every relative link of
README.md and docs/*.md reaches a file and, with a #fragment, a heading.

No app is started and nothing runs in a subprocess: the parser is built, the
bindings are read from the classes, the pages are read as text.
"""

from __future__ import annotations

import argparse
import importlib
import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from textual.binding import Binding
from textual.dom import DOMNode

import quadtank_tui.ui
from quadtank_tui.cli import build_parser

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]


# --- headings and sections -------------------------------------------------------

_HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*$")


def _headings(text: str) -> Iterator[tuple[int, str, int]]:
    """(level, title, line index) of each heading outside code blocks."""
    fenced = False
    for n, line in enumerate(text.splitlines()):
        if line.startswith("```"):
            fenced = not fenced
            continue
        match = None if fenced else _HEADING.match(line)
        if match:
            yield len(match.group(1)), match.group(2), n


def sections(text: str) -> dict[str, str]:
    """Each heading's title -> its text up to the next heading of its level or above."""
    lines = text.splitlines()
    heads = list(_headings(text))
    out = {}
    for i, (level, title, start) in enumerate(heads):
        end = next((n for lv, _, n in heads[i + 1:] if lv <= level), len(lines))
        out[title] = "\n".join(lines[start + 1:end])
    return out


def slug(title: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation dropped, spaces to '-'."""
    return re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")


def test_slug_follows_github() -> None:
    assert slug("A shared lab machine: the lab file, roles, locks") == "a-shared-lab-machine-the-lab-file-roles-locks"
    assert slug("`tui_cost.py`") == "tui_costpy"


# --- docs/cli.md against the parser ----------------------------------------------

def _commands(parser: argparse.ArgumentParser, path: str = "quadtank") -> Iterator[tuple[str, argparse.ArgumentParser]]:
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            seen: set[int] = set()
            for name, sub in action.choices.items():
                if id(sub) not in seen:  # an alias names the same parser
                    seen.add(id(sub))
                    yield from _commands(sub, f"{path} {name}")


def _options(parser: argparse.ArgumentParser) -> set[str]:
    return {s for a in parser._actions if not isinstance(a, argparse._HelpAction) for s in a.option_strings}


def _documented_options(section: str) -> set[str]:
    """The options a section's table rows name in their first column."""
    found = set()
    for line in section.splitlines():
        cells = line.split("|")
        if line.startswith("|") and len(cells) > 2:
            found.update(re.findall(r"(?<![\w-])(--?[A-Za-z][\w-]*)", cells[1]))
    return found


def test_every_command_and_option_is_in_cli_md_and_none_other() -> None:
    parsed = dict(_commands(build_parser()))
    documented = {title.strip("`"): body for title, body in sections((DOCS / "cli.md").read_text()).items()
                  if title.startswith("`quadtank")}
    assert sorted(set(parsed) - set(documented)) == [], "commands without a section in docs/cli.md"
    assert sorted(set(documented) - set(parsed)) == [], "sections of docs/cli.md naming no command"
    problems = []
    for command, parser in parsed.items():
        rows = _documented_options(documented[command])
        for option in sorted(_options(parser) - rows):
            problems.append(f"{command}: {option} is not in docs/cli.md")
        for option in sorted(rows - _options(parser)):
            problems.append(f"{command}: docs/cli.md lists {option}, which the command does not have")
    assert not problems, "\n".join(problems)


# --- docs/keys.md against the bindings -------------------------------------------

#: The section of docs/keys.md that holds each class's keys.  A class that binds
#: keys and is not here fails the test: give it a section, and a line here.
KEY_SECTIONS = {
    "QuadTankApp": "Everywhere",
    "MainScreen": "Main",
    "ChannelPanel": "The input signal panels",
    "SetupScreen": "Setup",
    "IdentifyScreen": "Identify",
    "DesignScreen": "Design",
    "HelpScreen": "Help",
    "Window": "Every window",
    "ParamWindow": "Every window",
    "ConfirmWindow": "Every window",
    "ChoiceWindow": "Every window",
    "Switch": "Every window",
    "ControllerTypeWindow": "Controller type",
    "PlotTypeWindow": "Plot type",
    "LoggingWindow": "Logging",
    "ParFileWindow": "Parameter files",
    "WaveWindow": "Reference wave",
    "TankWindow": "Tank (Main)",
    "TankSetupWindow": "Tank setup and plant window (Setup)",
    "PlantSetupWindow": "Tank setup and plant window (Setup)",
    "FaultWindow": "Faults",
    "GhostWindow": "Ghost run",
    "ExerciseWindow": "Exercise",
    "AttachedWindow": "Attached to a running session",
}

#: How docs/keys.md writes the keys Textual names by a word.
SPELLING = {
    "question_mark": "?", "plus": "+", "minus": "-",
    "right_square_bracket": "]", "left_square_bracket": "[",
    "right_curly_bracket": "}", "left_curly_bracket": "{",
    "escape": "Esc", "enter": "Enter", "end": "End", "tab": "Tab", "f1": "F1",
}


def _subclasses(cls: type) -> Iterator[type]:
    sub: type
    for sub in cls.__subclasses__():
        yield sub
        yield from _subclasses(sub)


def bound_classes() -> dict[str, list[Binding]]:
    """Every class of the interface that declares BINDINGS -> its own bindings.
    Only the modules whose text says BINDINGS are imported (the others, such as the
    design preview with python-control, take seconds and declare none)."""
    package = Path(quadtank_tui.ui.__file__).parent
    for source in sorted(package.rglob("*.py")):
        if "BINDINGS" in source.read_text():
            parts = source.relative_to(package).with_suffix("").parts
            importlib.import_module(".".join(("quadtank_tui.ui", *parts)).removesuffix(".__init__"))
    found: dict[str, list[Binding]] = {}
    for cls in set(_subclasses(DOMNode)):
        if cls.__module__.startswith("quadtank_tui.") and cls.__dict__.get("BINDINGS"):
            found[cls.__name__] = [b for b in cls.__dict__["BINDINGS"] if isinstance(b, Binding)]
    return found


def test_every_key_binding_is_in_keys_md_under_its_screen() -> None:
    classes = bound_classes()
    assert {"MainScreen", "SetupScreen", "LoggingWindow"} <= set(classes)  # the walk found them
    assert sorted(set(classes) - set(KEY_SECTIONS)) == [], "classes with keys and no section in docs/keys.md"
    pages = sections((DOCS / "keys.md").read_text())
    missing = []
    for name, bindings in sorted(classes.items()):
        section = pages.get(KEY_SECTIONS[name])
        assert section is not None, f"docs/keys.md has no section {KEY_SECTIONS[name]!r} (for {name})"
        written = set(re.findall(r"`([^`]+)`", section))
        for binding in bindings:
            for key in binding.key.split(","):
                if SPELLING.get(key, key) not in written:
                    missing.append(f"{name}: {SPELLING.get(key, key)!r} ({binding.action})")
    assert not missing, "keys not in their section of docs/keys.md:\n" + "\n".join(missing)


# --- links -----------------------------------------------------------------------

_LINK = re.compile(r"\]\(([^)\s]+)\)")


def _links(page: Path) -> Iterator[str]:
    fenced = False
    for line in page.read_text().splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced:
            yield from _LINK.findall(line)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_relative_links_reach_a_file_and_heading(page: Path) -> None:
    broken = []
    for link in _links(page):
        if re.match(r"[a-z]+:", link):
            continue  # http(s), mailto: not ours to check
        target, _, fragment = link.partition("#")
        path = (page.parent / target).resolve() if target else page
        if not path.exists():
            broken.append(f"{link}: no file {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}")
        elif fragment and path.suffix == ".md":
            anchors = {slug(title) for _, title, _ in _headings(path.read_text())}
            if fragment not in anchors:
                broken.append(f"{link}: no heading #{fragment} in {path.name}")
    assert not broken, "\n".join(broken)


def test_readme_keeps_the_two_commands_ci_runs() -> None:
    """.ci/run runs `make test`; the README says it, and the quick subset, literally."""
    readme = (ROOT / "README.md").read_text()
    assert "make test" in (ROOT / ".ci" / "run").read_text()
    for command in ("make run", "make test", '.venv/bin/python -m pytest -m "not wallclock"'):
        assert command in readme
    # and the commands `make test` runs (in parallel, issue 25), as the Makefile has them
    recipe = re.search(r"^test:.*\n((?:\t.*\n)+)", (ROOT / "Makefile").read_text(), re.M)
    assert recipe is not None
    for line in recipe[1].splitlines():
        assert f"`{line.strip().replace('$(BIN)/', '.venv/bin/')}`" in readme, line
    assert len(readme.splitlines()) < 200


# --- examples the pages give -----------------------------------------------------

def _code_blocks(page: Path, lang: str) -> list[str]:
    return re.findall(rf"^```{lang}\n(.*?)^```", page.read_text(), flags=re.S | re.M)


def test_the_lab_file_example_is_what_the_reader_reads() -> None:
    from quadtank_tui.session.lab import parse_lab_config
    from quadtank_tui.session.policy import UnattendedPolicy

    [example] = _code_blocks(DOCS / "sessions.md", "yaml")
    lab = parse_lab_config(example, name="docs/sessions.md")
    assert (lab.admin_group, lab.share_group, str(lab.runtime_dir)) == ("teachers", "lab", "/run/quadtank")
    assert str(lab.params_dir) == "/opt/quadtank/params"
    assert lab.unattended == UnattendedPolicy(keep_while_logging=True, grace_minutes=10)


def test_the_sample_script_example_is_a_valid_script() -> None:
    from quadtank_tui.files.script import parse_script

    [example] = _code_blocks(DOCS / "headless.md", "yaml")
    script = parse_script(example, name="docs/headless.md")
    assert [event.at for event in script.events] == [0, 0, 600, 600, 610]
