"""The modules of ev3conformance import each other without a cycle: every import counts, a
function's own too (read with ast, nothing imported)."""
from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[3] / "conformance" / "ev3conformance"
NAME = PKG.name


def imports_of(path: Path, modules: set[str]) -> set[str]:
    """The package's modules that the module at @p path imports, anywhere in it."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            heads = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = NAME if node.level else (node.module or "")
            if node.level and node.module:
                base = f"{NAME}.{node.module}"
            heads = [base] + [f"{base}.{a.name}" for a in node.names]
        else:
            continue
        for h in heads:
            parts = h.split(".")
            if parts[0] == NAME and len(parts) > 1 and parts[1] in modules:
                out.add(parts[1])
    return out


def cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of @p graph as the modules along it (the first one again at the end), or None."""
    state: dict[str, int] = {}   # 1 on the path being walked, 2 done
    path: list[str] = []

    def walk(m: str) -> list[str] | None:
        state[m] = 1
        path.append(m)
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                return path[path.index(n):] + [n]
            if n not in state:
                found = walk(n)
                if found:
                    return found
        path.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state:
            found = walk(m)
            if found:
                return found
    return None


def test_the_package_has_no_import_cycle():
    modules = {p.stem for p in PKG.glob("*.py")}
    graph = {m: imports_of(PKG / f"{m}.py", modules) - {m} for m in modules}
    assert graph["merged"] and graph["fleet_replay"], "no imports found: the reader is broken"
    found = cycle(graph)
    assert found is None, "import cycle: " + " -> ".join(found)


def test_a_cycle_is_found():
    assert cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert cycle({"a": {"b"}, "b": set()}) is None
