"""The ev3-conformance command line (codec subcommand)."""

import pytest

from ev3conformance.cli import main


def run(capsys, *argv):
    status = main(list(argv))
    return status, capsys.readouterr().out


def test_decode_hex(capsys):
    status, out = run(capsys, "codec", "decode", b"7:1:12:5:WORKING".hex())
    assert status == 0
    assert "accepted" in out and "type     5 PING" in out and '"WORKING"' in out
    assert out.rstrip().endswith("datagram 7:1:12:5:WORKING")


def test_decode_text_rejected(capsys):
    assert run(capsys, "codec", "decode", "--text", "7:1:12:5:%41") == \
        (1, "rejected: bad escape (field 4)\n")


def test_decode_bad_hex(capsys):
    assert main(["codec", "decode", "zz"]) == 2


def test_encode_text_and_hex(capsys):
    assert run(capsys, "codec", "encode", "7", "1", "12", "7", "a:b%", "x y") == \
        (0, "7:1:12:7:a%3Ab%25:x y\n")
    assert run(capsys, "codec", "encode", "--hex", "7", "1", "12", "20", "00ff", "-") == \
        (0, "7:1:12:20:%00%FF:\n")


def test_encode_refused(capsys):
    assert run(capsys, "codec", "encode", "70000", "1", "12", "8") == \
        (1, "rejected: out of range (field 0)\n")


def test_usage_error():
    with pytest.raises(SystemExit) as info:
        main(["codec"])
    assert info.value.code == 2
