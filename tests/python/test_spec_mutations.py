"""The catalogue of spec mutations (spec/tla/mutations.toml, docs/spec.md "Spec mutations") is
sound without running TLC: it parses, every mutation point is found exactly once in the current
spec (a point that moved or was edited fails here instead of silently passing `make
spec-mutate`), every model it names is one `make spec` runs, every guard class has a
mutation, and every property the make-spec models check is the expected killer of one mutation
or is named in docs/spec.md as covered otherwise."""

from __future__ import annotations

import importlib.util
import re
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SPEC = REPO / "spec" / "tla"
CATALOGUE = SPEC / "mutations.toml"


def _spec_tool():
    loader = importlib.util.spec_from_file_location("spec_tool", REPO / "tools" / "spec.py")
    module = importlib.util.module_from_spec(loader)
    loader.loader.exec_module(module)
    return module


spec_tool = _spec_tool()


def _cfg_properties(cfg: Path) -> set[str]:
    """The invariants and properties a cfg checks."""
    props, block = set(), False
    for line in cfg.read_text().splitlines():
        s = line.strip()
        if s in ("INVARIANTS", "INVARIANT", "PROPERTIES", "PROPERTY"):
            block = True
            continue
        if block and line[:1] in (" ", "\t") and s and not s.startswith("\\*"):
            props.add(s)
            continue
        block = False
        m = re.match(r"(INVARIANT|PROPERTY)\s+(\w+)$", s)
        if m:
            props.add(m.group(2))
    return props


def test_catalogue_loads_and_every_point_applies_once():
    muts = spec_tool.load_mutations()   # raises SystemExit naming every problem
    assert len(muts) >= 20
    for mu in muts:
        text = (SPEC / mu["module"]).read_text()
        assert text.count(mu["from"]) == 1, mu["id"]
        assert text.replace(mu["from"], mu["to"], 1) != text, mu["id"]


def test_guard_classes_covered():
    classes = {mu["class"] for mu in spec_tool.load_mutations() if mu["expect"] != "survives"}
    assert spec_tool.GUARD_CLASSES <= classes


def test_every_checked_property_has_a_killer_mutation_or_a_reason():
    killed = {mu["expect"].partition(":")[2] for mu in spec_tool.load_mutations()
              if mu["expect"] != "survives"}
    checked = set()
    for m in spec_tool.mutation_models().values():
        checked |= _cfg_properties(SPEC / m["cfg"])
    doc = (REPO / "docs" / "spec.md").read_text()
    section = doc[doc.index("## Spec mutations"):]
    section = section[:section.find("\n## ", 1)] if "\n## " in section[1:] else section
    unexplained = sorted(p for p in checked - killed if "`%s`" % p not in section)
    assert not unexplained, "properties with no killer mutation and no word in docs/spec.md: %s" % unexplained


def test_a_moved_mutation_point_fails_loudly(tmp_path):
    bad = tmp_path / "mutations.toml"
    text = CATALOGUE.read_text().replace(
        "from = 'Goto(a, s) == [a EXCEPT !.state = s, !.led = LedFor(s)]'",
        "from = 'Goto(a, s) == [a EXCEPT !.led = LedFor(s), !.state = s]'")
    assert text != CATALOGUE.read_text()
    bad.write_text(text)
    with pytest.raises(SystemExit, match=r"A01: the text to replace occurs 0 times in AgentLogic.tla"):
        spec_tool.load_mutations(str(bad))


def test_catalogue_is_toml_with_known_fields():
    with CATALOGUE.open("rb") as f:
        cat = tomllib.load(f)
    allowed = spec_tool.MUTATION_FIELDS | spec_tool.MUTATION_OPTIONAL
    for mu in cat["mutation"]:
        assert set(mu) <= allowed, mu["id"]
