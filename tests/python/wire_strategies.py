"""Hypothesis strategies for wire format v2: valid messages, valid datagrams, their mutations,
raw bytes, and messages encode() must refuse."""

from hypothesis import settings
from hypothesis import strategies as st

from ev3conformance import wire

TYPES = list(wire.MESSAGE_TYPES.values())
U16_MAX = 65535
U32_MAX = 4294967295


def examples(factor: float = 1.0) -> settings:
    """Settings for a test that deserves `factor` times the profile's max_examples."""
    return settings(max_examples=max(1, int(settings.default.max_examples * factor)))


# --- Valid ------------------------------------------------------------------------------------


def number_bytes(maximum: int) -> st.SearchStrategy[bytes]:
    return st.integers(0, maximum).map(lambda n: str(n).encode("ascii"))


# Text values: arbitrary bytes, with extra weight on the ones that need escaping.
_SPECIAL = b":%\x00\x1f\x7f\x80\xff "
text_values = st.one_of(
    st.binary(max_size=24),
    st.lists(st.sampled_from(list(_SPECIAL + b"aZ09~")), max_size=6).map(bytes),
)


def valid_value(kind: str) -> st.SearchStrategy[bytes]:
    if kind == "u16":
        return number_bytes(U16_MAX)
    if kind == "u32":
        return number_bytes(U32_MAX)
    if kind == "state":
        return st.sampled_from(wire.STATES)
    return text_values


@st.composite
def valid_messages(draw, types=None) -> wire.Message:
    """A message encode() accepts: any type, any count in min..max, every param valid."""
    mtype = draw(st.sampled_from(types or TYPES))
    # Counts near the limits matter most; the middle of 1..32 does not need to be dense.
    count = draw(st.one_of(st.integers(mtype.min_params, min(mtype.max_params, mtype.min_params + 3)),
                           st.integers(mtype.min_params, mtype.max_params),
                           st.sampled_from([mtype.min_params, mtype.max_params])))
    params = tuple(draw(valid_value(mtype.kind_of(i))) for i in range(count))
    msg = wire.Message(
        sender=draw(st.integers(0, U16_MAX)),
        receiver=draw(st.integers(0, U16_MAX)),
        msgid=draw(st.integers(0, U32_MAX)),
        type=mtype.number,
        params=params,
    )
    # Keep within 4096 bytes by shortening text params if the draw was unlucky.
    while len(wire._spell(msg)) > wire.MAX_DATAGRAM:
        msg = wire.Message(msg.sender, msg.receiver, msg.msgid, msg.type,
                           tuple(p[: len(p) // 2] if mtype.kind_of(i) == "text" else p
                                 for i, p in enumerate(msg.params)))
    return msg


valid_datagrams = valid_messages().map(wire.encode)


@st.composite
def long_valid_datagrams(draw) -> bytes:
    """Valid datagrams of 4000..4096 bytes (one big text param), to probe the length limit."""
    head = wire.Message(draw(st.integers(0, U16_MAX)), draw(st.integers(0, U16_MAX)),
                        draw(st.integers(0, U32_MAX)),
                        draw(st.sampled_from([7, 20])), (b"",))  # BEHAVIOUR, EVENT: one text param
    base = wire.encode(head)
    room = wire.MAX_DATAGRAM - len(base)
    size = draw(st.integers(room - 90, room))
    filler = draw(st.sampled_from([b"a", b"~", b"a:", b"%%", b"\x00b"]))
    value = bytearray()
    spent = 0
    while True:  # as many filler bytes as fit in `size` bytes once escaped
        byte = filler[len(value) % len(filler)]
        cost = 3 if wire.must_escape(byte) else 1
        if spent + cost > size:
            break
        value.append(byte)
        spent += cost
    return wire.encode(wire.Message(head.sender, head.receiver, head.msgid, head.type,
                                    (bytes(value),)))


# --- Mutations of valid datagrams -------------------------------------------------------------

INTERESTING_BYTES = list(b":%0123456789AFafG -+\x00\x1f\x7f\x80\xff~") + list(range(256))


def _positions(draw, data: bytes, extra: int = 0) -> int:
    """A position in data (or just past it with extra=1); half the time among the params."""
    params_start = _field_starts(data)[4] if len(_field_starts(data)) > 4 else None
    low = params_start if params_start is not None and draw(st.booleans()) else 0
    return draw(st.integers(min(low, len(data)), max(low, len(data) - 1 + extra)))


def _field_starts(data: bytes) -> list[int]:
    return [0] + [i + 1 for i, b in enumerate(data) if b == 0x3A]


@st.composite
def _mutate_once(draw, data: bytes) -> bytes:
    op = draw(st.sampled_from([
        "delete", "insert", "replace", "digit", "leading_zero", "add_param", "lower_escape",
        "needless_escape", "cut", "overlong", "bad_percent", "duplicate", "swap_type",
        "swap_param",
    ]))
    if op == "delete" and data:
        i = _positions(draw, data)
        return data[:i] + data[i + 1:]
    if op == "insert":
        i = _positions(draw, data, extra=1)
        return data[:i] + bytes([draw(st.sampled_from(INTERESTING_BYTES))]) + data[i:]
    if op == "replace" and data:
        i = _positions(draw, data)
        return data[:i] + bytes([draw(st.sampled_from(INTERESTING_BYTES))]) + data[i + 1:]
    if op == "digit":
        digits = [i for i, b in enumerate(data) if 0x30 <= b <= 0x39]
        if digits:
            i = draw(st.sampled_from(digits))
            return data[:i] + draw(st.sampled_from(b"0123456789")).to_bytes(1, "big") + data[i + 1:]
    if op == "leading_zero":
        i = draw(st.sampled_from(_field_starts(data)))
        return data[:i] + b"0" + data[i:]
    if op == "add_param":
        extra = draw(st.one_of(st.sampled_from([b"", b"x", b"0", b"IDLE", b"%3A", b"%41"]),
                               st.binary(max_size=6)))
        return data + b":" + extra
    if op == "lower_escape":
        escapes = [i for i in range(len(data) - 2) if data[i] == 0x25]
        if escapes:
            i = draw(st.sampled_from(escapes))
            return data[:i + 1] + data[i + 1:i + 3].lower() + data[i + 3:]
        i = _positions(draw, data, extra=1)
        return data[:i] + draw(st.sampled_from([b"%3a", b"%ff", b"%0a", b"%7f", b"%1f"])) + data[i:]
    if op == "needless_escape":
        plain = [i for i, b in enumerate(data) if 0x20 <= b <= 0x7E and b not in (0x3A, 0x25)]
        if plain:
            i = draw(st.sampled_from(plain))
            return data[:i] + b"%%%02X" % data[i] + data[i + 1:]
    if op == "cut" and data:
        return data[:_positions(draw, data)]
    if op == "overlong":
        target = draw(st.sampled_from([4096, 4097, 4098, 5000]))
        filler = draw(st.sampled_from([b"a", b"9", b":", b"%41"]))
        need = max(0, target - len(data))
        return data + (filler * need)[:need]
    if op == "bad_percent":
        i = _positions(draw, data, extra=1)
        return data[:i] + draw(st.sampled_from([b"%", b"%4", b"%G1", b"%%", b"%3", b"%:"])) + data[i:]
    if op == "duplicate" and data:
        i = _positions(draw, data)
        j = draw(st.integers(i, len(data)))
        return data[:j] + data[i:j] + data[j:]
    if op == "swap_type":
        starts = _field_starts(data)
        if len(starts) >= 4:
            i = starts[3]
            end = data.find(b":", i)
            end = len(data) if end < 0 else end
            new = draw(st.sampled_from([b"0", b"21", b"33", b"39", b"255", b"256"] +
                                       [str(n).encode() for n in wire.MESSAGE_TYPES]))
            return data[:i] + new + data[end:]
    if op == "swap_param":
        starts = _field_starts(data)
        if len(starts) > 4:
            i = draw(st.sampled_from(starts[4:]))
            end = data.find(b":", i)
            end = len(data) if end < 0 else end
            return data[:i] + escape_or_not(draw(bad_values), draw(st.booleans())) + data[end:]
    return data + b":"  # the chosen operation did not apply: still change something


def escape_or_not(value: bytes, escape: bool) -> bytes:
    return wire.escape_param(value) if escape else value


@st.composite
def mutated_datagrams(draw) -> bytes:
    long = draw(st.integers(0, 9)) == 0
    data = draw(long_valid_datagrams() if long else valid_datagrams)
    for _ in range(draw(st.integers(1, 3))):
        data = draw(_mutate_once(data))
    return data


raw_datagrams = st.one_of(
    st.binary(max_size=64),
    st.lists(st.sampled_from(list(b"0123456789::::%AFaf \x00\xff")), max_size=40).map(bytes),
)


@st.composite
def any_datagrams(draw) -> bytes:
    """Valid (1 in 4, a few of them near 4096 bytes), mutated (1 in 2) and raw (1 in 4)."""
    pick = draw(st.integers(0, 19))
    if pick < 4:
        return draw(valid_datagrams)
    if pick == 4:
        return draw(long_valid_datagrams())
    if pick < 15:
        return draw(mutated_datagrams())
    return draw(raw_datagrams)

# --- Messages for encode(): valid and refused -------------------------------------------------

_BIG = 2**64 - 1


@st.composite
def header_number(draw, maximum: int) -> int:
    """Mostly in range (so later fields get checked too), sometimes beyond it."""
    if draw(st.integers(0, 9)) < 9:
        return draw(st.integers(0, maximum))
    return draw(st.one_of(st.sampled_from([maximum + 1, 70000, 2**32, _BIG]),
                          st.integers(maximum + 1, _BIG),
                          # thousands of digits: the spelling's length decides too long or not
                          st.integers(20, 4150).map(lambda k: 10**k - 1)))


bad_values = st.one_of(
    st.sampled_from([b"", b"0", b"00", b"01", b"-1", b"+1", b" 1", b"1 ", b"65535", b"65536",
                     b"4294967295", b"4294967296", b"9" * 30, b"1" + b"0" * 100, b"idle",
                     b"IDLE", b"WORKING", b"PANIC ", b"x", b":", b"%", b"\x00"]),
    number_bytes(2**40),
    st.binary(max_size=8),
)


@st.composite
def any_messages(draw) -> wire.Message:
    """Messages for encode(): most valid or nearly so, with out-of-range numbers, unknown types,
    wrong param counts, bad typed params and oversize params mixed in."""
    if draw(st.integers(0, 3)) == 0:
        return draw(valid_messages())
    if draw(st.integers(0, 9)) < 8:
        type_number = draw(st.sampled_from(list(wire.MESSAGE_TYPES)))
    else:
        type_number = draw(st.one_of(st.sampled_from([0, 21, 33, 39, 40, 255, 256, 1000]),
                                     st.integers(0, 300)))
    mtype = wire.MESSAGE_TYPES.get(type_number)
    if mtype is not None:
        count = draw(st.integers(max(0, mtype.min_params - 1), min(mtype.max_params + 2, 34)))
    else:
        count = draw(st.integers(0, 3))
    params = []
    for i in range(count):
        kind = mtype.kind_of(i) if mtype is not None and i < mtype.max_params else "text"
        if draw(st.integers(0, 4)) == 0:
            params.append(draw(bad_values))
        else:
            params.append(draw(valid_value(kind)))
    if draw(st.integers(0, 9)) == 0:  # an oversize param, near the limit
        size = draw(st.integers(4000, 4200))
        params.append(draw(st.sampled_from([b"a", b":", b"0"])) * size)
    return wire.Message(
        sender=draw(header_number(U16_MAX)),
        receiver=draw(header_number(U16_MAX)),
        msgid=draw(header_number(U32_MAX)),
        type=type_number,
        params=tuple(params),
    )
