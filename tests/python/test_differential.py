"""Differential tests: the C++ codec (through `$EV3_BIN/ev3-codec`) against the reference codec.

For each input both sides must agree on accept/reject, on the reason and the field, on the
decoded content and on the re-encoding. The expected answer line is computed from
ev3conformance.wire and compared with the tool's line as a whole, so the tool's output format is
checked too:

    decode:  ok <sender> <receiver> <msgid> <type> <nparams> <p1> ... <pn> = <hex of encode(msg)>
             err <field> <reason>
    encode:  ok <hex datagram>
             err <field> <reason>

A disagreement is reported with the input, both answers and the rule of docs/protocol.md at stake;
decide from docs/protocol.md which side is wrong.
"""

from __future__ import annotations

import pytest
from hypothesis import event, example, given

import wire_strategies as ws
from ev3conformance import wire
from ev3conformance.wire import DecodeError, Message, decode, encode
from test_wire import ORDER, REJECTIONS

pytestmark = pytest.mark.differential

# --- Expected answers, from the reference codec -----------------------------------------------


def _hex_param(value: bytes) -> str:
    return value.hex() if value else "-"


def expected_decode(data: bytes) -> str:
    try:
        msg = decode(data)
    except DecodeError as err:
        return f"err {err.field} {err.reason}"
    fields = [str(n) for n in msg.header] + [str(len(msg.params))]
    fields += [_hex_param(p) for p in msg.params]
    return "ok " + " ".join(fields) + " = " + encode(msg).hex()


def encode_request(msg: Message) -> str:
    return " ".join([str(n) for n in msg.header] + [_hex_param(p) for p in msg.params])


def expected_encode(msg: Message) -> str:
    try:
        return "ok " + encode(msg).hex()
    except DecodeError as err:
        return f"err {err.field} {err.reason}"


# --- Reporting --------------------------------------------------------------------------------

_RULES = {
    "empty": "rule 1: no bytes at all -> empty (field 0)",
    "too long": "rule 2: more than 4096 bytes -> too long (field 0), before anything else",
    "too few fields": "rules 3/5: a missing header field k -> field k; fewer params than "
                      "min_params -> field 4+count",
    "bad number": "rule 3 / typed params: not a canonical number (empty, leading zero, sign, "
                  "non-digit)",
    "out of range": "rule 3 / typed params: above the maximum, type 0, or a state not in "
                    "IDLE|ACTIVE|WORKING|PAUSED|PANIC",
    "unknown type": "rule 3: a type in 1..255 that docs/messages.tsv does not define",
    "bad escape": "rule 4 / canonical form: '%' not followed by two upper-case hex digits, or "
                  "escaping a byte that need not be escaped",
    "non-printable byte": "rule 4: a param byte outside 0x20..0x7E",
    "too many params": "rule 4: when param i begins, i >= 32 or i >= max_params -> field 4+i",
}


def _explain(reference: str, tool: str) -> str:
    ref_parts, tool_parts = reference.split(" "), tool.split(" ")
    if ref_parts[0] != tool_parts[0]:
        what = f"accept/reject differs (reference {ref_parts[0]}, ev3-codec {tool_parts[0]})"
    elif ref_parts[0] == "err":
        what = "the reason or the field differs"
    elif "=" in ref_parts and "=" in tool_parts and \
            ref_parts[:ref_parts.index("=")] != tool_parts[:tool_parts.index("=")]:
        what = "the decoded message differs"
    else:
        what = "the (re-)encoding differs"
    reasons = {" ".join(p[2:]) for p in (ref_parts, tool_parts) if p[0] == "err"}
    rules = [f"  protocol.md: {_RULES[r]}" for r in sorted(reasons) if r in _RULES]
    return "\n".join([what] + rules)


def _show(data: bytes) -> str:
    text = repr(data) if len(data) <= 300 else repr(data[:300]) + f"... ({len(data)} bytes)"
    return text


def check_decode(codec, data: bytes) -> None:
    tool = codec.ask(data.hex())
    reference = expected_decode(data)
    if tool != reference:
        pytest.fail(
            "ev3-codec decode disagrees with the reference codec: "
            + _explain(reference, tool)
            + f"\n  input     : {_show(data)}"
            + f"\n  input hex : {data.hex() if len(data) <= 300 else data[:300].hex() + '...'}"
            + f"\n  ev3-codec : {tool[:600]}"
            + f"\n  reference : {reference[:600]}",
            pytrace=False)


def check_encode(codec, msg: Message) -> None:
    request = encode_request(msg)
    tool = codec.ask(request)
    reference = expected_encode(msg)
    if tool != reference:
        pytest.fail(
            "ev3-codec encode disagrees with the reference codec: "
            + _explain(reference, tool)
            + f"\n  message   : {msg!r}"[:800]
            + f"\n  input line: {request[:600]}"
            + f"\n  ev3-codec : {tool[:600]}"
            + f"\n  reference : {reference[:600]}",
            pytrace=False)


# --- Fixed cases: every documented rejection, the order cases, the worked example -------------

FIXED_DATAGRAMS = [d for d, _ in REJECTIONS] + [d for d, _ in ORDER] + [
    b"7:1:12:5:WORKING",
    b"0:0:0:8",
    b"65535:65535:4294967295:20:%00%3A%25%7F%FF",
    b"1:1:1:7" + b":a" * 32,
    b"1:1:1:7" + b":a" * 33,
    b"1:1:1:7:" + b"a" * 4088,
    b"1:1:1:7:" + b"a" * 4089,
    b"1:1:1:7:%3A%25",
    b"1:1:1:7:%3a",
    b"1:1:1:7:%41",
    b"1:1:1:3:" + b"9" * 4088,
    b"1:1:1:18:::",
    b"1:2:3:7:",
    b"::::",
    b":",
]


@pytest.mark.parametrize("data", FIXED_DATAGRAMS, ids=[repr(d[:30]) for d in FIXED_DATAGRAMS])
def test_decode_fixed(codec_decode, data):
    check_decode(codec_decode, data)


@pytest.mark.parametrize("byte", range(256))
def test_decode_every_byte_in_a_param(codec_decode, byte):
    check_decode(codec_decode, b"1:2:3:1:" + bytes([byte]))
    check_decode(codec_decode, b"1:2:3:1:%" + (b"%02X" % byte))
    check_decode(codec_decode, b"1:2:3:1:%" + (b"%02x" % byte))
    check_decode(codec_decode, bytes([byte]) + b":2:3:1:x")


FIXED_MESSAGES = [
    Message(7, 1, 12, 5, (b"WORKING",)),
    Message(0, 0, 0, 8),
    Message(65535, 65535, 4294967295, 20, (b"\x00:%\x7f\xff",)),
    Message(70000, 1, 1, 8),
    Message(1, 70000, 1, 8),
    Message(1, 1, 2**32, 8),
    Message(1, 1, 1, 0),
    Message(1, 1, 1, 256),
    Message(1, 1, 1, 34, (b"x",)),
    Message(1, 1, 1, 5),
    Message(1, 1, 1, 5, (b"idle",)),
    Message(1, 1, 1, 5, (b"IDLE", b"")),
    Message(1, 1, 1, 8, (b"",)),
    Message(1, 1, 1, 2, (b"65536",)),
    Message(1, 1, 1, 2, (b"007",)),
    Message(1, 1, 1, 3, (b"",)),
    Message(1, 1, 1, 3, (b"4294967296",)),
    Message(1, 1, 1, 7, (b"a",) * 32),
    Message(1, 1, 1, 7, (b"a",) * 33),
    Message(1, 1, 1, 7, (b"a" * 4088,)),
    Message(1, 1, 1, 7, (b"a" * 4089,)),
    Message(1, 1, 1, 7, (b":" * 1362,)),
    Message(1, 1, 1, 7, (b":" * 1363,)),
    Message(70000, 1, 1, 0, (b"a" * 5000,)),
    Message(1, 1, 1, 18, (b"", b"")),
]


@pytest.mark.parametrize("msg", FIXED_MESSAGES, ids=[encode_request(m)[:30] for m in FIXED_MESSAGES])
def test_encode_fixed(codec_encode, msg):
    check_encode(codec_encode, msg)


def test_decode_bad_input(codec_decode):
    for line in ("zz", "abc", "7g", "0x37"):
        answer = codec_decode.ask(line)
        assert answer.startswith("bad-input "), f"input line {line!r}: {answer!r}"
    check_decode(codec_decode, b"7:1:12:5:WORKING")  # still answering after bad input


def _outcome(answer: str) -> str:
    """A label for --hypothesis-show-statistics: accepted, or the reason (field class)."""
    parts = answer.split(" ")
    if parts[0] == "ok":
        return "accepted"
    field = int(parts[1])
    return f"{' '.join(parts[2:])} in {'the header' if field < 4 else 'a param'}"


# --- Hypothesis: decode -----------------------------------------------------------------------


@ws.examples(1)
@given(ws.valid_datagrams)
def test_decode_valid_datagrams(codec_decode, data):
    check_decode(codec_decode, data)
    event(_outcome(expected_decode(data)))


@ws.examples(4)
@given(ws.any_datagrams())
@example(b"")
@example(b"7:1:12:5:WORKING")
def test_decode_any_datagram(codec_decode, data):
    """Valid, mutated (byte deleted/inserted/replaced, digit changed, leading zero, extra param,
    lower-case or needless escape, cut, overlong) and raw random datagrams."""
    check_decode(codec_decode, data)
    event(_outcome(expected_decode(data)))


# --- Hypothesis: encode -----------------------------------------------------------------------


@ws.examples(1)
@given(ws.valid_messages())
def test_encode_valid_messages(codec_encode, msg):
    check_encode(codec_encode, msg)
    event(_outcome(expected_encode(msg)))


@ws.examples(4)
@given(ws.any_messages())
def test_encode_any_message(codec_encode, msg):
    """Valid messages and ones with out-of-range header numbers, unknown types, wrong param
    counts, bad typed params and oversize params."""
    check_encode(codec_encode, msg)
    event(_outcome(expected_encode(msg)))
