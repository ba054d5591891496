"""The reference codec's own message table against docs/messages.tsv, row by row."""

from pathlib import Path

import pytest

from ev3conformance import wire

TSV = Path(__file__).resolve().parents[2] / "docs" / "messages.tsv"


def _tsv_rows() -> list[list[str]]:
    rows = []
    for line in TSV.read_text(encoding="utf-8").splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        cols = line.split("\t")
        assert len(cols) == 6, f"messages.tsv: expected 6 tab-separated columns: {line!r}"
        rows.append(cols)
    return rows


def _python_row(t: wire.MessageType) -> list[str]:
    params = ",".join(str(p) for p in t.params) or "-"
    return [str(t.number), t.name, t.direction, str(t.min_params), str(t.max_params), params]


ROWS = _tsv_rows()


def test_tsv_is_readable():
    assert ROWS, f"no rows in {TSV}"


def test_same_types_in_same_order():
    assert [int(r[0]) for r in ROWS] == list(wire.MESSAGE_TYPES)


@pytest.mark.parametrize("row", ROWS, ids=[r[1] for r in ROWS])
def test_row_matches(row):
    number = int(row[0])
    assert number in wire.MESSAGE_TYPES, f"type {number} ({row[1]}) missing from wire.py"
    assert _python_row(wire.MESSAGE_TYPES[number]) == row


@pytest.mark.parametrize("row", ROWS, ids=[r[1] for r in ROWS])
def test_row_is_consistent(row):
    """Kinds are known; a non-repeating list has exactly max_params entries."""
    _, _, _, lo, hi, params = row
    lo, hi = int(lo), int(hi)
    assert 0 <= lo <= hi <= wire.MAX_PARAMS
    specs = [] if params == "-" else params.split(",")
    for spec in specs:
        kind, _, name = spec.partition(":")
        assert kind in wire.KINDS and name
    if specs and specs[-1].endswith("..."):
        assert len(specs) <= hi
    else:
        assert len(specs) == hi


def test_kind_of_repeats_last():
    behaviour = wire.TYPES_BY_NAME["BEHAVIOUR"]
    assert [behaviour.kind_of(i) for i in (0, 1, 31)] == ["text"] * 3
    not_ = wire.TYPES_BY_NAME["NOT"]
    assert (not_.kind_of(0), not_.kind_of(1)) == ("u32", "text")
    with pytest.raises(IndexError):
        not_.kind_of(2)
