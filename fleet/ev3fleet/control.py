"""A client of ev3-master's control socket (`--control PATH`, docs/programs.md "The control socket"):
one console line out, one answer line back, asked for in JSON."""

from __future__ import annotations

import asyncio
import json


class ControlError(Exception):
    """The master's control socket could not be reached or answered nothing (the message says why)."""


async def ask(path: str, line: str, timeout: float = 30.0) -> dict:
    """Sends console @line on a connection of its own and gives the master's JSON answer:
    {"ok": true, ...} or {"ok": false, "error": ...}. A command to robots is answered once every
    robot has answered it, so @timeout covers the master's resends."""
    if "\n" in line or "\r" in line:
        raise ControlError("a control line holds no line break")
    try:
        reader, writer = await asyncio.wait_for(asyncio.open_unix_connection(path), 5.0)
    except (OSError, asyncio.TimeoutError) as e:
        raise ControlError(f"control socket {path}: {e.strerror if isinstance(e, OSError) else 'no answer'}") from None
    try:
        writer.write(f"--json {line}\n".encode())
        await writer.drain()
        raw = await asyncio.wait_for(reader.readline(), timeout)
    except (OSError, asyncio.TimeoutError):
        raise ControlError(f"control socket {path}: no answer to '{line}' within {timeout:g} s") from None
    finally:
        writer.close()
    if not raw:
        raise ControlError(f"control socket {path}: the master closed the connection")
    try:
        return json.loads(raw)
    except ValueError:
        raise ControlError(f"control socket {path}: an answer that is not JSON: {raw[:80]!r}") from None
