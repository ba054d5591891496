"""Unit tests of the reference codec (conformance/ev3conformance/wire.py) against docs/protocol.md."""

import pytest

from ev3conformance import wire
from ev3conformance.wire import DecodeError, Message, decode, encode


def rejects(data: bytes) -> tuple[str, int]:
    with pytest.raises(DecodeError) as info:
        decode(data)
    return (info.value.reason, info.value.field)


def refuses(msg: Message) -> tuple[str, int]:
    with pytest.raises(DecodeError) as info:
        encode(msg)
    return (info.value.reason, info.value.field)


# --- The worked example -----------------------------------------------------------------------


def test_worked_example():
    msg = decode(b"7:1:12:5:WORKING")
    assert msg == Message(sender=7, receiver=1, msgid=12, type=5, params=(b"WORKING",))
    assert msg.type_name == "PING"
    assert encode(msg) == b"7:1:12:5:WORKING"


def test_reason_names_are_the_documented_ones():
    assert wire.REASONS == ("empty", "too long", "too few fields", "bad number", "out of range",
                            "unknown type", "bad escape", "non-printable byte", "too many params")


def test_reason_must_be_documented():
    with pytest.raises(AssertionError):
        DecodeError("bad thing", 0)


# --- Every rejection reason with its field ----------------------------------------------------

REJECTIONS = [
    # 1. empty, 2. too long
    (b"", ("empty", 0)),
    (b"x" * 4097, ("too long", 0)),
    (b"1:1:1:7:" + b"%" * 4089, ("too long", 0)),
    # 3. header: too few fields, in the field that is missing
    (b"7", ("too few fields", 1)),
    (b"7:1", ("too few fields", 2)),
    (b"7:1:12", ("too few fields", 3)),
    # header: bad number (empty, leading zero, sign, non-digit, '%', control, high byte, space)
    (b":1:12:5:IDLE", ("bad number", 0)),
    (b"07:1:12:5:IDLE", ("bad number", 0)),
    (b"+7:1:12:5:IDLE", ("bad number", 0)),
    (b"-7:1:12:5:IDLE", ("bad number", 0)),
    (b" 7:1:12:5:IDLE", ("bad number", 0)),
    (b"7 :1:12:5:IDLE", ("bad number", 0)),
    (b"7:00:12:5:IDLE", ("bad number", 1)),
    (b"7:1a:12:5:IDLE", ("bad number", 1)),
    (b"7:1:%31:5:IDLE", ("bad number", 2)),
    (b"7:1:1\x002:5:IDLE", ("bad number", 2)),
    (b"7:1:12:\xb5:IDLE", ("bad number", 3)),
    (b"7:1:12:", ("bad number", 3)),
    (b"7:1:12::IDLE", ("bad number", 3)),
    (b"7:1:12:05:IDLE", ("bad number", 3)),
    # header: out of range
    (b"65536:1:12:5:IDLE", ("out of range", 0)),
    (b"7:65536:12:5:IDLE", ("out of range", 1)),
    (b"7:1:4294967296:5:IDLE", ("out of range", 2)),
    (b"7:1:12:256:IDLE", ("out of range", 3)),
    (b"7:1:12:0:IDLE", ("out of range", 3)),
    (b"7:1:12:0", ("out of range", 3)),
    # header: unknown type (in 1..255, not in the table)
    (b"7:1:12:34:x", ("unknown type", 3)),
    (b"7:1:12:255", ("unknown type", 3)),
    # 4. params: too many params (type's max), non-printable, bad escape, kind
    (b"7:1:12:5:WORKING:", ("too many params", 5)),
    (b"7:1:12:8:", ("too many params", 4)),
    (b"7:1:12:4:1:why:", ("too many params", 6)),
    (b"1:2:3:1:A\x7f", ("non-printable byte", 4)),
    (b"1:2:3:1:A\x1fB", ("non-printable byte", 4)),
    (b"1:2:3:1:\xff", ("non-printable byte", 4)),
    (b"1:2:3:1:\n", ("non-printable byte", 4)),
    (b"1:2:3:1:%", ("bad escape", 4)),
    (b"1:2:3:1:%4", ("bad escape", 4)),
    (b"1:2:3:1:%G0", ("bad escape", 4)),
    (b"1:2:3:1:%41", ("bad escape", 4)),
    (b"1:2:3:1:%3a", ("bad escape", 4)),
    (b"1:2:3:1:%7e", ("bad escape", 4)),
    (b"1:2:3:1:%7f", ("bad escape", 4)),
    (b"1:2:3:1:%0a", ("bad escape", 4)),
    (b"1:2:3:1:%20", ("bad escape", 4)),
    (b"1:2:3:1:%7E", ("bad escape", 4)),
    (b"1:2:3:7:ok:%3", ("bad escape", 5)),
    (b"1:2:3:2:007", ("bad number", 4)),
    (b"1:2:3:2:", ("bad number", 4)),
    (b"1:2:3:2:-1", ("bad number", 4)),
    (b"1:2:3:2:1 ", ("bad number", 4)),
    (b"1:2:3:2:%25", ("bad number", 4)),
    (b"1:2:3:2:65536", ("out of range", 4)),
    (b"1:2:3:3:4294967296", ("out of range", 4)),
    (b"1:2:3:4:4294967296:why", ("out of range", 4)),
    (b"1:2:3:4:12:why:extra", ("too many params", 6)),
    (b"1:2:3:5:working", ("out of range", 4)),
    (b"1:2:3:5:", ("out of range", 4)),
    (b"1:2:3:5:WORKING%00", ("out of range", 4)),
    # 5. too few params: the field where the first missing param would be
    (b"7:1:12:5", ("too few fields", 4)),
    (b"7:1:12:4:1", ("too few fields", 5)),
    (b"7:1:12:18:A:mode", ("too few fields", 6)),
    (b"7:1:12:1", ("too few fields", 4)),
]


@pytest.mark.parametrize("data,expected", REJECTIONS, ids=[repr(d[:40]) for d, _ in REJECTIONS])
def test_rejection(data, expected):
    assert rejects(data) == expected


def test_every_reason_is_covered_above():
    assert {reason for _, (reason, _) in REJECTIONS} == set(wire.REASONS)


# --- Left-to-right order: the first problem found is the one reported -------------------------

ORDER = [
    (b"x" * 4097, ("too long", 0)),  # too long before anything in the bytes
    (b"07:x:12", ("bad number", 0)),  # sender before receiver
    (b"7:x", ("bad number", 1)),  # a bad field before the missing one
    (b"65536:00", ("out of range", 0)),  # out of range before a later bad number
    (b"7:1:12:0:%zz", ("out of range", 3)),  # the type before params
    (b"7:1:12:99:%zz", ("unknown type", 3)),
    (b"1:2:3:5:%41:x", ("bad escape", 4)),  # param 0's problem before too many params at 5
    (b"1:2:3:5:idle:x", ("out of range", 4)),  # param 0's kind before too many params at 5
    (b"1:2:3:4:x:\x00", ("bad number", 4)),  # param 0's kind before param 1's bytes
    (b"1:2:3:7:a\x00%41", ("non-printable byte", 4)),  # bytes left to right
    (b"1:2:3:7:a%41\x00", ("bad escape", 4)),
    (b"1:2:3:7:%\x00", ("bad escape", 4)),  # the '%' comes first
    (b"1:2:3:2:%41", ("bad escape", 4)),  # bytes before the kind
    (b"1:2:3:2:\x00", ("non-printable byte", 4)),
    (b"1:2:3:18:a:\x00", ("non-printable byte", 5)),  # param 1 before too few at 6
    (b"1:2:3:9:%zz", ("too many params", 4)),  # too many before the param's bytes
]


@pytest.mark.parametrize("data,expected", ORDER, ids=[repr(d[:40]) for d, _ in ORDER])
def test_first_problem_from_the_left(data, expected):
    assert rejects(data) == expected


# --- Canonical escapes ------------------------------------------------------------------------


def test_required_escapes_are_accepted():
    assert decode(b"1:2:3:1:%3A").params == (b":",)
    assert decode(b"1:2:3:1:%25").params == (b"%",)
    assert decode(b"1:2:3:1:%00%1F%7F%80%FF").params == (b"\x00\x1f\x7f\x80\xff",)
    assert decode(b"1:2:3:1:a%3Ab%25c").params == (b"a:b%c",)


@pytest.mark.parametrize("byte", range(256))
def test_each_byte_value_is_carried_canonically(byte):
    value = bytes([byte])
    data = encode(Message(1, 2, 3, 1, (value,)))
    if byte == 0x3A or byte == 0x25 or not 0x20 <= byte <= 0x7E:
        assert data == b"1:2:3:1:%" + b"%02X" % byte
        # the same escape in lower case, where it differs, is a bad escape
        lower = b"1:2:3:1:%" + b"%02x" % byte
        if lower != data:
            assert rejects(lower) == ("bad escape", 4)
        # and the raw byte (other than ':', which splits) is not accepted
        if byte != 0x3A:
            raw = b"1:2:3:1:" + value
            assert rejects(raw) == (("bad escape", 4) if byte == 0x25 else ("non-printable byte", 4))
    else:
        assert data == b"1:2:3:1:" + value
        # escaping a byte that need not be escaped is a bad escape
        assert rejects(b"1:2:3:1:%" + b"%02X" % byte) == ("bad escape", 4)
    assert decode(data).params == (value,)


def test_escape_param():
    assert wire.escape_param(b"a:b%c d\x00\xff~") == b"a%3Ab%25c d%00%FF~"
    assert wire.escape_param(b"") == b""


def test_empty_params():
    assert decode(b"1:2:3:7:").params == (b"",)
    assert decode(b"1:2:3:7::").params == (b"", b"")
    assert rejects(b"1:2:3:8:") == ("too many params", 4)
    assert encode(Message(1, 2, 3, 7, (b"",))) == b"1:2:3:7:"
    assert encode(Message(1, 2, 3, 20, (b"", b"", b""))) == b"1:2:3:20:::"


# --- Size limits: 4096 bytes, 32 params --------------------------------------------------------


def test_4096_bytes_accepted_4097_rejected():
    head = b"1:1:1:7:"
    ok = head + b"a" * (4096 - len(head))
    assert len(ok) == 4096
    assert decode(ok).params == (b"a" * (4096 - len(head)),)
    assert encode(decode(ok)) == ok
    assert rejects(ok + b"a") == ("too long", 0)


def test_encode_4096_bytes_accepted_4097_refused():
    head = b"1:1:1:7:"
    value = b"a" * (4096 - len(head))
    assert len(encode(Message(1, 1, 1, 7, (value,)))) == 4096
    assert refuses(Message(1, 1, 1, 7, (value + b"a",))) == ("too long", 0)
    # escaping counts: one ':' takes three bytes
    assert refuses(Message(1, 1, 1, 7, (value[:-2] + b":",))) == ("too long", 0)
    assert len(encode(Message(1, 1, 1, 7, (value[:-3] + b":",)))) == 4096


def test_32_params_accepted_33_rejected():
    ok = b"1:1:1:7" + b":a" * 32
    assert len(decode(ok).params) == 32
    assert rejects(ok + b":a") == ("too many params", 36)
    assert rejects(ok + b":") == ("too many params", 36)
    assert len(encode(Message(1, 1, 1, 7, (b"a",) * 32))) == len(ok)
    assert refuses(Message(1, 1, 1, 7, (b"a",) * 33)) == ("too many params", 36)
    assert refuses(Message(1, 1, 1, 18, (b"",) * 40)) == ("too many params", 36)


# --- Per-type min and max ----------------------------------------------------------------------


def _valid_value(kind: str) -> bytes:
    return {"u16": b"65535", "u32": b"4294967295", "state": b"IDLE", "text": b"t:%\x00"}[kind]


@pytest.mark.parametrize("mtype", list(wire.MESSAGE_TYPES.values()), ids=lambda t: t.name)
def test_per_type_min_and_max(mtype):
    def msg(count):
        return Message(9, 8, 7, mtype.number, tuple(_valid_value(mtype.kind_of(i)) for i in range(count)))

    for count in {mtype.min_params, mtype.max_params}:
        m = msg(count)
        assert decode(encode(m)) == m
    if mtype.min_params > 0:
        short = msg(mtype.min_params - 1)
        assert refuses(short) == ("too few fields", 4 + mtype.min_params - 1)
        assert rejects(wire._spell(short)) == ("too few fields", 4 + mtype.min_params - 1)
    long = Message(9, 8, 7, mtype.number, msg(mtype.max_params).params + (b"x",))
    assert refuses(long) == ("too many params", 4 + mtype.max_params)
    assert rejects(wire._spell(long)) == ("too many params", 4 + mtype.max_params)


# --- Numbers: header fields and u16/u32 params -------------------------------------------------

HEADER_BOUNDS = [(0, 65535), (1, 65535), (2, 4294967295), (3, 255)]


@pytest.mark.parametrize("field,maximum", HEADER_BOUNDS)
def test_header_bounds(field, maximum):
    def datagram(value: bytes) -> bytes:
        parts = [b"1", b"1", b"1", b"3", b"0"]
        parts[field] = value
        return b":".join(parts)

    if field == 3:  # 255 is a type number, just not one the table defines
        assert rejects(datagram(b"255")) == ("unknown type", 3)
    else:
        assert decode(datagram(str(maximum).encode())).header[field] == maximum
    assert rejects(datagram(str(maximum + 1).encode())) == ("out of range", field)
    assert rejects(datagram(b"9" * 3000)) == ("out of range", field)
    assert rejects(datagram(b"1" + b"0" * 4000)) == ("out of range", field)
    assert rejects(datagram(b"0" + str(maximum).encode())) == ("bad number", field)
    assert rejects(datagram(b"00")) == ("bad number", field)
    if field != 3:
        assert decode(datagram(b"0")).header[field] == 0
    header = [1, 1, 1, 3]
    header[field] = maximum + 1
    assert refuses(Message(*header, (b"0",))) == ("out of range", field)
    header[field] = -1
    assert refuses(Message(*header, (b"0",))) == ("out of range", field)
    header[field] = 10**40
    assert refuses(Message(*header, (b"0",))) == ("out of range", field)


@pytest.mark.parametrize("type_,maximum", [(2, 65535), (3, 4294967295), (6, 4294967295),
                                           (15, 4294967295), (4, 4294967295)])
def test_number_params(type_, maximum):
    extra = (b"why",) if type_ == 4 else ()

    def m(value: bytes) -> Message:
        return Message(1, 2, 3, type_, (value,) + extra)

    for good in (b"0", b"1", b"10", str(maximum).encode()):
        assert decode(encode(m(good))) == m(good)
    for bad, reason in [(str(maximum + 1).encode(), "out of range"),
                        (b"9" * 4000, "out of range"),
                        (b"1" + b"0" * 4000, "out of range"),
                        (b"00", "bad number"), (b"01", "bad number"), (b"", "bad number"),
                        (b"+1", "bad number"), (b"-0", "bad number"), (b"1.0", "bad number"),
                        (b" 1", "bad number"), (b"1e3", "bad number"), (b"\x00", "bad number"),
                        (b"\xd9\xa1", "bad number"), (b":", "bad number")]:
        assert refuses(m(bad)) == (reason, 4), bad
        spelled = wire._spell(m(bad))
        if len(spelled) <= 4096:
            assert rejects(spelled) == (reason, 4), bad


def test_huge_digit_strings_in_a_full_datagram():
    data = b"1:1:1:3:" + b"9" * (4096 - 8)
    assert len(data) == 4096
    assert rejects(data) == ("out of range", 4)
    assert rejects(b"9" * 4096) == ("out of range", 0)
    assert rejects(b"1:1:" + b"9" * 4092) == ("out of range", 2)


# --- State params ------------------------------------------------------------------------------


@pytest.mark.parametrize("state", [b"IDLE", b"ACTIVE", b"WORKING", b"PAUSED", b"PANIC"])
def test_states_accepted(state):
    data = b"7:1:12:5:" + state
    assert decode(data).params == (state,)
    assert encode(decode(data)) == data


@pytest.mark.parametrize("state", [b"", b"idle", b"Idle", b"IDLE ", b" IDLE", b"WORK", b"UNKNOWN",
                                   b"IDLE\x00", b"PANIC:", b"0"])
def test_bad_states(state):
    assert refuses(Message(7, 1, 12, 5, (state,))) == ("out of range", 4)
    assert rejects(wire._spell(Message(7, 1, 12, 5, (state,)))) == ("out of range", 4)


# --- encode refusals and their order ----------------------------------------------------------


def test_encode_refusals():
    assert refuses(Message(1, 2, 3, 0)) == ("out of range", 3)
    assert refuses(Message(1, 2, 3, 256)) == ("out of range", 3)
    assert refuses(Message(1, 2, 3, 34, (b"x",))) == ("unknown type", 3)
    assert refuses(Message(70000, 70000, 3, 0)) == ("out of range", 0)
    assert refuses(Message(1, 70000, 3, 0)) == ("out of range", 1)
    assert refuses(Message(1, 2, 2**32, 0)) == ("out of range", 2)
    assert refuses(Message(1, 2, 3, 5, (b"idle", b"x"))) == ("out of range", 4)
    assert refuses(Message(1, 2, 3, 5, (b"IDLE", b"x"))) == ("too many params", 5)
    assert refuses(Message(1, 2, 3, 4)) == ("too few fields", 4)
    # too long is found first, as decode finds it first in the spelling
    assert refuses(Message(70000, 2, 3, 0, (b"x" * 5000,))) == ("too long", 0)


def test_encode_huge_header_numbers():
    # the spelling's length decides first: 4000 digits fit in 4096 bytes, 5000 do not
    assert refuses(Message(10**4000, 1, 1, 8)) == ("out of range", 0)
    assert refuses(Message(1, 1, 10**4085, 8)) == ("out of range", 2)
    assert refuses(Message(1, 1, 10**4090, 8)) == ("too long", 0)
    assert refuses(Message(1, 1, 1, 10**5000)) == ("too long", 0)
    assert refuses(Message(1, 1, 1, -10**5000)) == ("too long", 0)
    assert refuses(Message(1, 1, 1, 8, (b"x" * 4000,))) == ("too many params", 4)


def test_message_types():
    with pytest.raises(TypeError):
        Message("1", 2, 3, 5, (b"IDLE",))
    with pytest.raises(TypeError):
        Message(1, 2, 3, 5, ("IDLE",))
    with pytest.raises(TypeError):
        Message(True, 2, 3, 5, (b"IDLE",))
    m = Message(1, 2, 3, 7, [bytearray(b"x"), memoryview(b"y")])
    assert m.params == (b"x", b"y") and isinstance(m.params, tuple)
    assert m == Message(1, 2, 3, 7, (b"x", b"y"))
    with pytest.raises(AttributeError):
        m.sender = 4  # frozen


def test_decode_accepts_bytes_like():
    assert decode(bytearray(b"7:1:12:5:IDLE")) == decode(memoryview(b"7:1:12:5:IDLE"))


def test_decode_error_equality_and_repr():
    assert DecodeError("bad escape", 4) == DecodeError("bad escape", 4)
    assert DecodeError("bad escape", 4) != DecodeError("bad escape", 5)
    assert repr(DecodeError("too long", 0)) == "DecodeError('too long', 0)"
    assert str(DecodeError("too long", 0)) == "too long (field 0)"
    assert isinstance(DecodeError("empty", 0), ValueError)
