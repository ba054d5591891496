"""ev3-conformance: command line of the conformance package.

    ev3-conformance codec decode HEX              decode a datagram given in hex
    ev3-conformance codec decode --text TEXT      decode a datagram given as its (ASCII) text
    ev3-conformance codec encode S R MSGID TYPE [PARAM ...]
                                                  encode a message; params as text (UTF-8),
                                                  or in hex with --hex ('-' for an empty one)

Exit status: 0 accepted, 1 rejected, 2 usage error.
"""

from __future__ import annotations

import argparse
import sys

from ev3conformance import wire


def _show_param(value: bytes) -> str:
    """A param value as readable text: printable ASCII as itself, other bytes as \\xNN."""
    return "".join(chr(b) if 0x20 <= b <= 0x7E and b != 0x5C else f"\\x{b:02x}" for b in value)


def _describe(msg: wire.Message) -> str:
    name = msg.type_name or "?"
    lines = [
        f"sender   {msg.sender}",
        f"receiver {msg.receiver}",
        f"msgid    {msg.msgid}",
        f"type     {msg.type} {name}",
        f"params   {len(msg.params)}",
    ]
    mtype = wire.MESSAGE_TYPES.get(msg.type)
    for i, value in enumerate(msg.params):
        kind = mtype.kind_of(i) if mtype else "?"
        lines.append(f"  [{i}] field {wire.FIRST_PARAM_FIELD + i} {kind:5} \"{_show_param(value)}\"")
    return "\n".join(lines)


def _rejected(err: wire.DecodeError) -> int:
    print(f"rejected: {err.reason} (field {err.field})")
    return 1


def _cmd_decode(args: argparse.Namespace) -> int:
    if args.text:
        data = args.datagram.encode("latin-1")
    else:
        try:
            data = bytes.fromhex(args.datagram)
        except ValueError as exc:
            print(f"ev3-conformance: not hex: {exc}", file=sys.stderr)
            return 2
    try:
        msg = wire.decode(data)
    except wire.DecodeError as err:
        return _rejected(err)
    print("accepted")
    print(_describe(msg))
    print(f"datagram {wire.encode(msg).decode('ascii')}")
    return 0


def _cmd_encode(args: argparse.Namespace) -> int:
    params = []
    for p in args.params:
        if args.hex:
            try:
                params.append(b"" if p == "-" else bytes.fromhex(p))
            except ValueError as exc:
                print(f"ev3-conformance: param not hex: {exc}", file=sys.stderr)
                return 2
        else:
            params.append(p.encode("utf-8"))
    msg = wire.Message(args.sender, args.receiver, args.msgid, args.type, tuple(params))
    try:
        data = wire.encode(msg)
    except wire.DecodeError as err:
        return _rejected(err)
    print(data.decode("ascii"))
    return 0


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ev3-conformance", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    codec = sub.add_parser("codec", help="the reference codec of wire format v1")
    modes = codec.add_subparsers(dest="mode", required=True)

    dec = modes.add_parser("decode", help="decode one datagram")
    dec.add_argument("datagram", help="the datagram in hex (or as text with --text)")
    dec.add_argument("--text", action="store_true", help="the datagram is given as text")
    dec.set_defaults(run=_cmd_decode)

    enc = modes.add_parser("encode", help="encode one message")
    enc.add_argument("sender", type=int)
    enc.add_argument("receiver", type=int)
    enc.add_argument("msgid", type=int)
    enc.add_argument("type", type=int)
    enc.add_argument("params", nargs="*")
    enc.add_argument("--hex", action="store_true", help="params are hex ('-' for empty)")
    enc.set_defaults(run=_cmd_encode)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())
