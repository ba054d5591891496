"""The Python reference of signed datagrams (ev3conformance.signing) against docs/protocol.md's
example, which the C++ test (tests/cpp/codec/auth_test.cpp) checks too."""

from __future__ import annotations

from pathlib import Path

import pytest

from ev3conformance.signing import counter, key_id, read_key, seal, unseal

DOC = Path(__file__).resolve().parents[2] / "docs" / "protocol.md"


def test_the_documented_example():
    key = bytes(range(32))
    signed = seal(b"1:7:5:9", key, counter(1000))
    assert signed == b"1:7:5:9\n630DCD2900000000FA000000849096EF452C8149E97A4E1B7A7E2636"
    text = DOC.read_text()
    assert "`1:7:5:9` LF `630DCD29` `00000000FA000000` `849096EF452C8149E97A4E1B7A7E2636`" in text
    assert unseal(signed) == (b"1:7:5:9", key_id(key), counter(1000))


def test_key_file_text():
    assert read_key("ab" * 32 + "\n") == bytes([0xAB]) * 32
    for bad in ("ab" * 31, "ab" * 32 + "\n\n", "zz" * 32):
        with pytest.raises(ValueError):
            read_key(bad)
