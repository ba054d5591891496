"""Reference codec of wire format v2 (docs/protocol.md).

This module is written to be read next to docs/protocol.md: it is the reference that other
implementations (the C++ library in libev3proto/include/ev3proto/wire.hpp) are checked against,
so it favours the order of the rules in the document over speed.

    decode(data: bytes) -> Message     raises DecodeError(reason, field)
    encode(msg: Message) -> bytes      raises DecodeError(reason, field) for a refused message

A rejection carries one of the reason names of docs/protocol.md (the REASONS tuple) and the field
it is in: 0 sender, 1 receiver, 2 msgid, 3 type, 4 + i for param i.

The message table (MESSAGE_TYPES) is this module's own copy of docs/messages.tsv; the test
tests/python/test_message_table.py compares the two row by row. To add a type, add one `_type(...)`
line to _TABLE.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "MAX_DATAGRAM",
    "MAX_PARAMS",
    "REASONS",
    "STATES",
    "KINDS",
    "HEADER_FIELDS",
    "DecodeError",
    "Message",
    "MessageType",
    "ParamSpec",
    "MESSAGE_TYPES",
    "TYPES_BY_NAME",
    "decode",
    "encode",
    "escape_param",
    "must_escape",
]

# --- Limits ------------------------------------------------------------------------------------

MAX_DATAGRAM = 4096  # bytes per datagram
MAX_PARAMS = 32  # params per datagram, whatever the type allows

# The header fields in wire order: (name, largest value). Field index = position in this tuple.
HEADER_FIELDS: tuple[tuple[str, int], ...] = (
    ("sender", 65535),
    ("receiver", 65535),
    ("msgid", 4294967295),
    ("type", 255),
)
TYPE_FIELD = 3
FIRST_PARAM_FIELD = 4

# --- Rejection reasons, exactly as docs/protocol.md names them ---------------------------------

EMPTY = "empty"
TOO_LONG = "too long"
TOO_FEW_FIELDS = "too few fields"
BAD_NUMBER = "bad number"
OUT_OF_RANGE = "out of range"
UNKNOWN_TYPE = "unknown type"
BAD_ESCAPE = "bad escape"
NON_PRINTABLE = "non-printable byte"
TOO_MANY_PARAMS = "too many params"

REASONS: tuple[str, ...] = (
    EMPTY,
    TOO_LONG,
    TOO_FEW_FIELDS,
    BAD_NUMBER,
    OUT_OF_RANGE,
    UNKNOWN_TYPE,
    BAD_ESCAPE,
    NON_PRINTABLE,
    TOO_MANY_PARAMS,
)


class DecodeError(ValueError):
    """A datagram (or a message to encode) is rejected: `reason` in REASONS, `field` its index."""

    def __init__(self, reason: str, field: int) -> None:
        if reason not in REASONS:
            raise AssertionError(f"not a reason of docs/protocol.md: {reason!r}")
        super().__init__(f"{reason} (field {field})")
        self.reason = reason
        self.field = field

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, DecodeError):
            return NotImplemented
        return (self.reason, self.field) == (other.reason, other.field)

    def __hash__(self) -> int:
        return hash((self.reason, self.field))

    def __repr__(self) -> str:
        return f"DecodeError({self.reason!r}, {self.field})"


# --- Param kinds -------------------------------------------------------------------------------

STATES: tuple[bytes, ...] = (b"IDLE", b"ACTIVE", b"WORKING", b"PAUSED", b"PANIC")

# kind -> the largest number it accepts (None: not a number kind)
_NUMBER_KINDS = {"u16": 65535, "u32": 4294967295}
KINDS: tuple[str, ...] = ("u16", "u32", "state", "text")


@dataclass(frozen=True)
class ParamSpec:
    """One param of a type: its kind, its name, and whether it repeats up to max_params."""

    kind: str
    name: str
    repeats: bool = False

    def __str__(self) -> str:  # the notation of docs/messages.tsv
        return f"{self.kind}:{self.name}" + ("..." if self.repeats else "")


@dataclass(frozen=True)
class MessageType:
    """One row of the message table."""

    number: int
    name: str
    direction: str
    min_params: int
    max_params: int
    params: tuple[ParamSpec, ...]

    def kind_of(self, index: int) -> str:
        """The kind of param `index` (0-based); a repeating last param covers the rest."""
        if index < len(self.params):
            return self.params[index].kind
        if self.params and self.params[-1].repeats:
            return self.params[-1].kind
        raise IndexError(f"{self.name} has no param {index}")


def _type(number: int, name: str, direction: str, min_params: int, max_params: int,
          *params: str) -> MessageType:
    """Build a table row from the notation of docs/messages.tsv: "kind:name", "kind:name..."."""
    specs = []
    for text in params:
        repeats = text.endswith("...")
        kind, _, pname = text.removesuffix("...").partition(":")
        specs.append(ParamSpec(kind, pname, repeats))
    return MessageType(number, name, direction, min_params, max_params, tuple(specs))


# The message types of wire format v2. Keep in the order of docs/messages.tsv.
_TABLE: tuple[MessageType, ...] = (
    _type(1, "AGENT", "agent->0", 1, 32, "text:model", "text:device..."),
    _type(2, "MASTER", "master->agent", 1, 1, "u16:announced_id"),
    _type(3, "ACK", "both", 1, 1, "u32:acked_msgid"),
    _type(4, "NOT", "agent->master", 2, 2, "u32:refused_msgid", "text:reason"),
    _type(5, "PING", "agent->master", 1, 1, "state:state"),
    _type(6, "PONG", "master->agent", 1, 1, "u32:ping_msgid"),
    _type(7, "BEHAVIOUR", "master->agent", 1, 32, "text:name", "text:argument..."),
    _type(8, "START", "master->agent", 0, 0),
    _type(9, "STOP", "master->agent", 0, 0),
    _type(10, "PAUSE", "master->agent", 0, 0),
    _type(11, "RESUME", "master->agent", 0, 0),
    _type(12, "STANDBY", "master->agent", 0, 0),
    _type(13, "CONTINUE", "master->agent", 0, 0),
    _type(14, "RESTART", "master->agent", 0, 0),
    _type(15, "ACTION_OK", "agent->master", 1, 1, "u32:action"),
    _type(16, "ACTION_INTERR", "agent->master", 2, 2, "u32:action", "text:event"),
    _type(17, "ACTION_ERR", "agent->master", 2, 2, "u32:action", "text:error"),
    _type(18, "SENSOR_VALUE", "agent->master", 3, 32, "text:port", "text:mode", "text:value..."),
    _type(19, "PANIC", "agent->0", 0, 0),
    _type(20, "EVENT", "agent->master", 1, 32, "text:event", "text:detail..."),
    # Relay and election (spec/tla/Election.tla, docs/election.md).
    _type(21, "RELAY_REQ", "agent->0", 1, 3, "u32:epoch", "u32:score", "u32:members_epoch"),
    _type(22, "RELAY_OFFER", "agent->agent", 2, 2, "u32:epoch", "u16:master"),
    _type(23, "RELAY_ACCEPT", "agent->agent", 2, 2, "u32:epoch", "u16:master"),
    _type(24, "RELAY_ROUTE", "agent->master", 2, 2, "u32:epoch", "u16:relayed"),
    _type(25, "RELAY", "both", 2, 2, "u16:target", "text:datagram"),
    _type(26, "RELAY_DROP", "agent->agent", 1, 1, "u32:epoch"),
    _type(27, "ELECT", "agent->0", 3, 3, "u32:epoch", "u32:score", "u32:members_epoch"),
    _type(28, "VOTE", "agent->agent", 2, 2, "u32:epoch", "u16:candidate"),
    _type(29, "LEADER", "master->0", 2, 32, "u32:epoch", "u16:leader", "u16:member..."),
    _type(30, "EPOCH_STALE", "both", 1, 1, "u32:epoch"),
    _type(31, "EPOCH_CMD", "master->agent", 2, 2, "u32:epoch", "text:datagram"),
    _type(32, "HANDOVER", "master->master", 2, 32, "u32:epoch", "text:registry..."),
    _type(33, "PREVOTE_OK", "agent->agent", 1, 1, "u32:epoch"),
    # Reliable reports (spec/tla/Reports.tla, docs/reports.md).
    _type(40, "REPORT", "agent->master", 3, 3, "u32:seq", "u32:first", "text:datagram"),
    _type(41, "REPORT_DROPPED", "agent->master", 2, 2, "u32:first", "u32:last"),
    _type(42, "REPORT_ACK", "master->agent", 1, 1, "u32:stored"),
)

MESSAGE_TYPES: dict[int, MessageType] = {t.number: t for t in _TABLE}
TYPES_BY_NAME: dict[str, MessageType] = {t.name: t for t in _TABLE}


def _check_table() -> None:
    """The table must make sense on its own; a mistake here is a bug in this file."""
    assert len(MESSAGE_TYPES) == len(_TABLE) and len(TYPES_BY_NAME) == len(_TABLE)
    for t in _TABLE:
        assert 1 <= t.number <= 255, t
        assert 0 <= t.min_params <= t.max_params <= MAX_PARAMS, t
        assert all(p.kind in KINDS for p in t.params), t
        assert all(not p.repeats for p in t.params[:-1]), t
        if t.params and t.params[-1].repeats:
            assert len(t.params) <= t.max_params, t
        else:
            assert len(t.params) == t.max_params, t


_check_table()

# --- Bytes -------------------------------------------------------------------------------------

_DIGITS = b"0123456789"
_UPPER_HEX = b"0123456789ABCDEF"
_COLON = 0x3A
_PERCENT = 0x25


def _printable(byte: int) -> bool:
    return 0x20 <= byte <= 0x7E


def must_escape(byte: int) -> bool:
    """True when a param byte is written %XX: ':', '%' and every byte outside 0x20..0x7E."""
    return byte in (_COLON, _PERCENT) or not _printable(byte)


# How each byte value is written in a param.
_SPELLING: tuple[bytes, ...] = tuple(
    b"%%%02X" % byte if must_escape(byte) else bytes([byte]) for byte in range(256)
)


def escape_param(value: bytes) -> bytes:
    """The canonical spelling of a param value: %XX (upper-case) exactly where required."""
    return b"".join(_SPELLING[byte] for byte in value)


def _unescape_param(raw: bytes, field: int) -> bytes:
    """The value of one param as written on the wire, checking its bytes left to right."""
    out = bytearray()
    i = 0
    while i < len(raw):
        byte = raw[i]
        if not _printable(byte):
            raise DecodeError(NON_PRINTABLE, field)
        if byte == _PERCENT:
            digits = raw[i + 1:i + 3]
            if len(digits) != 2 or any(d not in _UPPER_HEX for d in digits):
                raise DecodeError(BAD_ESCAPE, field)  # missing, non-hex or lower-case digits
            value = int(digits, 16)
            if not must_escape(value):
                raise DecodeError(BAD_ESCAPE, field)  # e.g. %41: 'A' is written as itself
            out.append(value)
            i += 3
        else:
            out.append(byte)
            i += 1
    return bytes(out)


# --- Numbers -----------------------------------------------------------------------------------


def _is_canonical_number(text: bytes) -> bool:
    """number = "0" / ( %x31-39 *DIGIT ): no sign, no leading zero, no spaces, not empty."""
    if text == b"0":
        return True
    return len(text) >= 1 and text[0] in b"123456789" and all(c in _DIGITS for c in text)


def _number(text: bytes, maximum: int, field: int) -> int:
    """A canonical number no larger than `maximum`, or the rejection for it."""
    if not _is_canonical_number(text):
        raise DecodeError(BAD_NUMBER, field)
    # Compare lengths first: a digit string may be thousands of digits long.
    if len(text) > len(str(maximum)) or int(text) > maximum:
        raise DecodeError(OUT_OF_RANGE, field)
    return int(text)


def _check_kind(kind: str, value: bytes, field: int) -> None:
    """A param value (after unescaping) against its kind."""
    if kind in _NUMBER_KINDS:
        _number(value, _NUMBER_KINDS[kind], field)
    elif kind == "state":
        if value not in STATES:
            raise DecodeError(OUT_OF_RANGE, field)
    elif kind != "text":
        raise AssertionError(f"unknown kind {kind!r}")


# --- Message -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Message:
    """A message: header numbers and the params' values (unescaped bytes).

    A Message may hold values encode() refuses (a sender of 70000, a bad PING state, too many
    params): that is how refusals are tested. Only the Python types are checked here.
    """

    sender: int
    receiver: int
    msgid: int
    type: int
    params: tuple[bytes, ...] = ()

    def __post_init__(self) -> None:
        for name in ("sender", "receiver", "msgid", "type"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool):
                raise TypeError(f"Message.{name} must be an int, not {type(value).__name__}")
        params = tuple(self.params)
        for p in params:
            if not isinstance(p, (bytes, bytearray, memoryview)):
                raise TypeError(f"Message params must be bytes, not {type(p).__name__}")
        object.__setattr__(self, "params", tuple(bytes(p) for p in params))

    @property
    def header(self) -> tuple[int, int, int, int]:
        return (self.sender, self.receiver, self.msgid, self.type)

    @property
    def type_name(self) -> str | None:
        t = MESSAGE_TYPES.get(self.type)
        return t.name if t else None


# --- decode ------------------------------------------------------------------------------------


def decode(data: bytes) -> Message:
    """Decode one datagram, or raise DecodeError for the first problem from the left.

    The steps are those of "Rejection: reasons and their order" in docs/protocol.md.
    """
    data = bytes(data)
    # 1. and 2.: the datagram as a whole.
    if len(data) == 0:
        raise DecodeError(EMPTY, 0)
    if len(data) > MAX_DATAGRAM:
        raise DecodeError(TOO_LONG, 0)

    # ':' only ever separates fields (a param writes it as %3A), so splitting on it is exact.
    fields = data.split(b":")

    # 3. The four header fields, in order.
    header = []
    for index, (_name, maximum) in enumerate(HEADER_FIELDS):
        if index >= len(fields):
            raise DecodeError(TOO_FEW_FIELDS, index)
        header.append(_number(fields[index], maximum, index))
    sender, receiver, msgid, type_number = header
    if type_number == 0:
        raise DecodeError(OUT_OF_RANGE, TYPE_FIELD)
    mtype = MESSAGE_TYPES.get(type_number)
    if mtype is None:
        raise DecodeError(UNKNOWN_TYPE, TYPE_FIELD)

    # 4. The params, in order: count limit when it begins, then its bytes, then its kind.
    params = []
    for i, raw in enumerate(fields[FIRST_PARAM_FIELD:]):
        field = FIRST_PARAM_FIELD + i
        if i >= MAX_PARAMS or i >= mtype.max_params:
            raise DecodeError(TOO_MANY_PARAMS, field)
        value = _unescape_param(raw, field)
        _check_kind(mtype.kind_of(i), value, field)
        params.append(value)

    # 5. Too few params for the type.
    if len(params) < mtype.min_params:
        raise DecodeError(TOO_FEW_FIELDS, FIRST_PARAM_FIELD + len(params))

    return Message(sender, receiver, msgid, type_number, tuple(params))


# --- encode ------------------------------------------------------------------------------------


# A number of more than MAX_DATAGRAM digits makes any spelling too long; its digits need not be
# written out (Python refuses str() of ints beyond a few thousand digits by default).
_TOO_MANY_DIGITS = 10**MAX_DATAGRAM


def _spell_number(n: int) -> bytes:
    if abs(n) >= _TOO_MANY_DIGITS:
        return b"9" * (MAX_DATAGRAM + 1)
    return str(n).encode("ascii")


def _spell(msg: Message) -> bytes:
    """The canonical spelling of a message, whether or not it is valid."""
    parts = [_spell_number(n) for n in msg.header]
    parts += [escape_param(p) for p in msg.params]
    return b":".join(parts)


def encode(msg: Message) -> bytes:
    """The canonical datagram of a message, or DecodeError for a message decode would reject.

    encode refuses a message with the reason and field decode gives for the message's canonical
    spelling, so the checks come in decode's order: too long (field 0) first, then the header
    fields, then each param (too many params when it begins, then its kind), then too few params.
    A negative header number, which has no spelling, is out of range in its field.
    """
    data = _spell(msg)
    if len(data) > MAX_DATAGRAM:
        raise DecodeError(TOO_LONG, 0)

    for index, ((_name, maximum), value) in enumerate(zip(HEADER_FIELDS, msg.header)):
        if not 0 <= value <= maximum:
            raise DecodeError(OUT_OF_RANGE, index)
    if msg.type == 0:
        raise DecodeError(OUT_OF_RANGE, TYPE_FIELD)
    mtype = MESSAGE_TYPES.get(msg.type)
    if mtype is None:
        raise DecodeError(UNKNOWN_TYPE, TYPE_FIELD)

    for i, value in enumerate(msg.params):
        field = FIRST_PARAM_FIELD + i
        if i >= MAX_PARAMS or i >= mtype.max_params:
            raise DecodeError(TOO_MANY_PARAMS, field)
        _check_kind(mtype.kind_of(i), value, field)

    if len(msg.params) < mtype.min_params:
        raise DecodeError(TOO_FEW_FIELDS, FIRST_PARAM_FIELD + len(msg.params))

    return data
