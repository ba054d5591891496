"""The signed form of a datagram (docs/protocol.md, "Signed datagrams"), for tools and tests that
speak to nodes in signed mode: `datagram LF keyid counter tag`, the tag the first 16 bytes of
HMAC-SHA-256(key, everything before it) (Python's hmac and hashlib)."""

from __future__ import annotations

import hashlib
import hmac

TRAILER = 1 + 8 + 16 + 32
SEQ_BITS = 22


def key_id(key: bytes) -> bytes:
    """The key's id: the first 4 bytes of SHA-256(key), 8 upper-case hex digits."""
    return hashlib.sha256(key).hexdigest()[:8].upper().encode()


def read_key(text: str) -> bytes:
    """The 32-byte key of a key file's text (64 hex digits, a trailing newline allowed)."""
    t = text[:-1] if text.endswith("\n") else text
    key = bytes.fromhex(t) if len(t) == 64 else b""
    if len(key) != 32:
        raise ValueError("a key file holds 64 hex digits (a 32-byte key)")
    return key


def seal(datagram: bytes, key: bytes, counter: int) -> bytes:
    """@p datagram signed with @p key and @p counter (boot * 2^22 + seq)."""
    head = datagram + b"\n" + key_id(key) + b"%016X" % counter
    return head + hmac.new(key, head, hashlib.sha256).hexdigest()[:32].upper().encode()


def counter(boot: int, seq: int = 0) -> int:
    return (boot << SEQ_BITS) | seq


def unseal(data: bytes) -> tuple[bytes, bytes, int]:
    """(datagram, key id, counter) of a signed datagram, the tag unchecked; ValueError when @p data
    has no trailer."""
    if len(data) < TRAILER or data[-TRAILER] != 0x0A:
        raise ValueError("not a signed datagram")
    t = data[-TRAILER + 1:]
    return data[:-TRAILER], t[:8], int(t[8:24], 16)
