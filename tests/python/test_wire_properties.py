"""Hypothesis properties of the reference codec alone (no C++ involved)."""

from hypothesis import given, note
from hypothesis import strategies as st

import wire_strategies as ws
from ev3conformance import wire
from ev3conformance.wire import DecodeError, decode, encode


@given(ws.valid_messages())
def test_decode_of_encode_is_identity(msg):
    data = encode(msg)
    note(f"datagram {data!r}")
    assert decode(data) == msg


@given(st.one_of(ws.valid_datagrams, ws.long_valid_datagrams()))
def test_encode_of_decode_is_identity(data):
    assert encode(decode(data)) == data


def _field_ok(err: DecodeError) -> bool:
    if err.reason in ("empty", "too long"):
        return err.field == 0
    if err.reason in ("bad number", "out of range"):
        return 0 <= err.field <= 4 + wire.MAX_PARAMS - 1
    if err.reason == "unknown type":
        return err.field == 3
    if err.reason == "too few fields":
        return 1 <= err.field <= 4 + wire.MAX_PARAMS - 1
    if err.reason == "too many params":
        return 4 <= err.field <= 4 + wire.MAX_PARAMS
    return 4 <= err.field <= 4 + wire.MAX_PARAMS - 1  # bad escape, non-printable byte


@given(ws.any_datagrams())
def test_any_datagram_is_rejected_or_canonical(data):
    """Every accepted datagram is the one spelling of its message; a rejection is well formed."""
    try:
        msg = decode(data)
    except DecodeError as err:
        assert err.reason in wire.REASONS
        assert _field_ok(err), err
    else:
        assert encode(msg) == data


@given(ws.any_messages())
def test_encode_refuses_exactly_what_decode_rejects(msg):
    """encode refuses a message with decode's reason and field for its canonical spelling."""
    spelled = wire._spell(msg)
    try:
        expected = decode(spelled)
    except DecodeError as err:
        expected = err
    try:
        got = encode(msg)
    except DecodeError as err:
        got = err
    if isinstance(expected, DecodeError):
        assert got == expected
    else:
        assert expected == msg and got == spelled


@given(ws.any_messages().filter(lambda m: min(m.header) >= 0))
def test_encode_never_crashes(msg):
    try:
        data = encode(msg)
    except DecodeError as err:
        assert _field_ok(err), err
    else:
        assert len(data) <= wire.MAX_DATAGRAM and decode(data) == msg
