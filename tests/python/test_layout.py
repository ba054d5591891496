"""The tree's dependency rule (docs/programs.md, "Layout"): programs -> programs/ (the shared program
library, ev3prog) -> io/ -> libev3proto. agent/ and master/ include and link nothing of each other;
the shared layers include nothing of a program, and sim/ and tools/ nothing of agent/ or master/. And one JSON string escaper (ev3proto/json.hpp).

Read from the sources as text: a quoted #include is resolved the way the build resolves it (next to
the including file, then the include directories of the layers it may use), and each CMakeLists.txt
is searched for the other program's targets and directories.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SOURCES = (".cpp", ".hpp", ".h", ".cc")
INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"', re.M)

# Each layer, the include directories its build sees, and what it must never reach.
LAYERS = {
    "agent": (["agent", "programs", "io", "libev3proto/include"], ["master"]),
    "master": (["master", "programs", "io", "libev3proto/include"], ["agent"]),
    "programs": (["programs", "io", "libev3proto/include"], ["agent", "master", "sim", "tools"]),
    "io": (["io", "libev3proto/include"], ["agent", "master", "programs", "sim", "tools"]),
    "sim": (["sim", "programs", "io", "libev3proto/include"], ["agent", "master"]),
    "tools": (["tools", "programs", "io", "libev3proto/include"], ["agent", "master"]),
}
# Targets a layer's CMakeLists.txt must not link.
TARGETS = {
    "agent": ["ev3master_lib", "ev3-master"],
    "master": ["ev3agent_lib", "ev3-agent"],
    "programs": ["ev3agent_lib", "ev3master_lib"],
    "io": ["ev3agent_lib", "ev3master_lib", "ev3prog"],
    "sim": ["ev3agent_lib", "ev3master_lib"],
    "tools": ["ev3agent_lib", "ev3master_lib"],
}


def _sources(root: Path, layer: str) -> list[Path]:
    return sorted(p for p in (root / layer).rglob("*") if p.suffix in SOURCES)


def resolve(root: Path, src: Path, name: str, dirs: list[str]) -> Path | None:
    """Where the build finds `#include "name"` of @p src: its own directory, then @p dirs."""
    for base in [src.parent] + [root / d for d in dirs]:
        cand = (base / name).resolve()
        if cand.is_file():
            return cand
    return None


def violations(layer: str, root: Path = REPO) -> list[str]:
    dirs, forbidden = LAYERS[layer]
    bad = []
    for src in _sources(root, layer):
        for name in INCLUDE.findall(src.read_text(encoding="utf-8")):
            where = resolve(root, src, name, dirs)
            # Not found through the allowed directories: found only in a forbidden one is a violation.
            if where is None:
                for f in forbidden:
                    if (root / f / name).is_file() or any((root / f).rglob(Path(name).name)):
                        bad.append(f"{src.relative_to(root)}: #include \"{name}\" is {f}/'s")
                continue
            rel = where.relative_to(root.resolve())
            if rel.parts[0] in forbidden:
                bad.append(f"{src.relative_to(root)}: #include \"{name}\" reaches {rel}")
    for cmake in sorted((root / layer).rglob("CMakeLists.txt")):
        text = re.sub(r"#.*", "", cmake.read_text(encoding="utf-8"))
        for t in TARGETS[layer]:
            if re.search(rf"(?<![\w-]){re.escape(t)}(?![\w-])", text):
                bad.append(f"{cmake.relative_to(root)}: links {t}")
        for f in forbidden:
            if re.search(rf"\.\./{f}\b|/{f}/", text):
                bad.append(f"{cmake.relative_to(root)}: names {f}/")
    return bad


@pytest.mark.parametrize("layer", sorted(LAYERS))
def test_dependencies_point_one_way(layer: str) -> None:
    assert violations(layer) == []


def test_the_check_sees_a_sideways_include_and_link(tmp_path: Path) -> None:
    """The check itself, on a small tree: an agent source that includes master's options header
    (by its name and by a relative path) and an agent CMakeLists.txt that links master's library."""
    (tmp_path / "master").mkdir()
    (tmp_path / "master" / "master_options.hpp").write_text("#pragma once\n")
    (tmp_path / "agent").mkdir()
    (tmp_path / "agent" / "main.cpp").write_text('#include "master_options.hpp"\n#include "../master/master_options.hpp"\n')
    (tmp_path / "agent" / "CMakeLists.txt").write_text("target_link_libraries(x PRIVATE ev3master_lib)\n")
    found = violations("agent", tmp_path)
    assert found == ["agent/main.cpp: #include \"master_options.hpp\" is master/'s",
                     "agent/main.cpp: #include \"../master/master_options.hpp\" reaches master/master_options.hpp",
                     "agent/CMakeLists.txt: links ev3master_lib"], found


def test_one_json_string_escaper() -> None:
    """Only ev3proto/json.hpp writes JSON's \\u00XX escape in the C++ outside the tests."""
    writers = []
    for top in ("agent", "master", "programs", "io", "sim", "tools", "libev3proto"):
        for src in sorted((REPO / top).rglob("*")):
            if src.suffix not in SOURCES:
                continue
            text = src.read_text(encoding="utf-8")
            if re.search(r'"\\\\u00"|\\\\u%04x', text):
                writers.append(str(src.relative_to(REPO)))
    assert writers == ["libev3proto/include/ev3proto/json.hpp"]
