"""The tree's dependency rule (docs/programs.md, "Layout"): programs -> programs/ (the shared program
library, ev3prog) -> io/ -> libev3proto. agent/ and master/ include and link nothing of each other;
the shared layers include nothing of a program, and sim/ and tools/ nothing of agent/ or master/. And one JSON string escaper (ev3proto/json.hpp).
Inside the library (docs/core.md, "The library's layers"): what joins the layers -> the cores ->
behaviour/ -> robot/ -> the vocabulary, each header including only its own layer and those below, with no cycle.

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


# ---------------------------------------------------------------- inside the library

LIB = Path("libev3proto/include/ev3proto")

# The library's layers, lowest first (docs/core.md, "The library's layers"). A header may include
# headers of its own layer and of the layers below it, never one above. Each entry names the headers
# of a layer by their paths under libev3proto/include/ev3proto/ (a folder: every header in it).
LIBRARY_LAYERS = [
    ("vocabulary", ["timers.hpp", "messages.hpp", "msgids.hpp", "json.hpp", "decimal.hpp", "ring.hpp", "dedupe.hpp",
                    "deadline_list.hpp", "wire.hpp", "auth.hpp", "core.hpp"]),
    ("robot", ["robot/"]),
    ("behaviour", ["behaviour/"]),
    ("cores", ["election/", "durable.hpp", "reports.hpp", "agent_types.hpp", "agent_outbox.hpp", "agent.hpp", "master_registry.hpp",
               "master_types.hpp", "record.hpp", "master.hpp", "node.hpp"]),
    ("joins", ["robot_runtime.hpp", "robot_link.hpp", "rules.hpp", "trace.hpp"]),
]


def layer_of(rel: str, layers=LIBRARY_LAYERS) -> int | None:
    """The index in @p layers of the header at @p rel (a path under ev3proto/), or None."""
    for i, (_, members) in enumerate(layers):
        for m in members:
            if rel == m or (m.endswith("/") and rel.startswith(m)):
                return i
    return None


def library_includes(root: Path = REPO) -> dict[str, list[str]]:
    """Each header of the library (its path under ev3proto/) and the library headers it includes,
    resolved as the build resolves them: next to the header, then from libev3proto/include. A header
    the build generates (behaviour/builtins_text.hpp) is named by the path it is included by."""
    lib = root / LIB
    out: dict[str, list[str]] = {}
    for src in sorted(lib.rglob("*.hpp")):
        names = []
        for name in INCLUDE.findall(src.read_text(encoding="utf-8")):
            where = resolve(root, src, name, ["libev3proto/include"])
            if where is not None:
                try:
                    names.append(where.relative_to(lib.resolve()).as_posix())
                except ValueError:
                    pass  # outside the library
            elif name.startswith("ev3proto/"):
                names.append(name[len("ev3proto/"):])
        out[src.relative_to(lib).as_posix()] = names
    return out


def layering_violations(root: Path = REPO, layers=LIBRARY_LAYERS) -> list[str]:
    """Headers in no layer, includes that reach a layer above, and include cycles."""
    graph = library_includes(root)
    bad = []
    for src, names in graph.items():
        mine = layer_of(src, layers)
        if mine is None:
            bad.append(f"{src}: in no layer of LIBRARY_LAYERS")
            continue
        for name in names:
            theirs = layer_of(name, layers)
            if theirs is not None and theirs > mine:
                bad.append(f"{src} ({layers[mine][0]}): #include of {name} ({layers[theirs][0]}, a layer above)")
    # No cycle, even inside one layer: a depth-first walk that meets a header still on its path.
    state: dict[str, int] = {}

    def walk(h: str, path: list[str]) -> None:
        state[h] = 1
        for n in graph.get(h, []):
            if state.get(n) == 1:
                bad.append("include cycle: " + " -> ".join(path[path.index(n):] + [n]))
            elif n not in state:
                walk(n, path + [n])
        state[h] = 2

    for h in sorted(graph):
        if h not in state:
            walk(h, [h])
    return bad


def test_the_library_is_layered() -> None:
    bad = layering_violations()
    assert bad == [], "\n".join(bad)


def test_the_layering_check_sees_an_upward_include_and_a_cycle(tmp_path: Path) -> None:
    """The check itself, on a small library: robot/ including behaviour/ (a layer above) while
    behaviour/ includes robot/, and a header in no layer."""
    lib = tmp_path / LIB
    (lib / "robot").mkdir(parents=True)
    (lib / "behaviour").mkdir()
    (lib / "robot" / "runtime.hpp").write_text('#include "../behaviour/automaton.hpp"\n#include "../timers.hpp"\n')
    (lib / "behaviour" / "automaton.hpp").write_text('#include "ev3proto/robot/runtime.hpp"\n')
    (lib / "timers.hpp").write_text("#pragma once\n")
    (lib / "stray.hpp").write_text("#pragma once\n")
    found = layering_violations(tmp_path)
    assert found == ["robot/runtime.hpp (robot): #include of behaviour/automaton.hpp (behaviour, a layer above)",
                     "stray.hpp: in no layer of LIBRARY_LAYERS",
                     "include cycle: behaviour/automaton.hpp -> robot/runtime.hpp -> behaviour/automaton.hpp"], found
