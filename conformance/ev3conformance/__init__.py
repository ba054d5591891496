"""Conformance checks for libev3proto.

`ev3conformance.wire` is the reference codec of wire format v2 (docs/protocol.md).
"""

from ev3conformance.wire import (
    MAX_DATAGRAM,
    MAX_PARAMS,
    MESSAGE_TYPES,
    DecodeError,
    Message,
    MessageType,
    decode,
    encode,
)

__all__ = [
    "MAX_DATAGRAM",
    "MAX_PARAMS",
    "MESSAGE_TYPES",
    "DecodeError",
    "Message",
    "MessageType",
    "decode",
    "encode",
]
