"""An ev3-sim world for drawing: its bounds, walls, boxes, floor patches and start poses, in
centimetres. ev3-sim is the one reader of the world format (docs/devices.md "World files"):
`ev3-sim world FILE` checks a file and prints it as JSON, which this module takes, from a file
holding that JSON or by running ev3-sim on a world file."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

COLOURS = {"none": "#ffffff", "black": "#222222", "blue": "#3b6fd8", "green": "#3fa34d", "yellow": "#f2d21b",
           "red": "#d83b3b", "white": "#f4f4f4", "brown": "#8b5a2b"}

Point = tuple[float, float]


class WorldError(ValueError):
    """A world that cannot be drawn (the message says why: ev3-sim's own error for a bad file)."""


@dataclass
class World:
    bounds: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    walls: list[tuple[float, float, float, float]] = field(default_factory=list)
    boxes: list[list[Point]] = field(default_factory=list)                 # polygons
    patches: list[tuple[str, list[Point]]] = field(default_factory=list)  # colour, polygon; bottom first
    starts: list[tuple[float, float, float]] = field(default_factory=list)

    @staticmethod
    def read(path: Path, sim: str | None = None) -> "World":
        """The world of @path: the JSON `ev3-sim world` prints, or a world file, which the ev3-sim
        at @sim (default: `ev3-sim` on PATH) reads."""
        try:
            text = Path(path).read_text()
        except (OSError, UnicodeDecodeError) as e:
            raise WorldError(f"{path}: {getattr(e, 'strerror', None) or e}") from None
        if text.lstrip().startswith("{"):
            return World.from_json(text, str(path))
        exe = sim or shutil.which("ev3-sim")
        if exe is None or not os.path.isfile(exe) or not os.access(exe, os.X_OK):
            why = f"{sim} is not an executable file" if sim else "no ev3-sim on PATH"
            raise WorldError(f"{path} is a world file: reading it needs ev3-sim ({why}); give --sim PATH, or the "
                             f"JSON `ev3-sim world {path}` prints")
        try:
            r = subprocess.run([exe, "world", str(path)], capture_output=True, text=True, timeout=30)
        except (OSError, subprocess.TimeoutExpired) as e:
            raise WorldError(f"{exe} world {path}: {getattr(e, 'strerror', None) or e}") from None
        if r.returncode != 0:
            raise WorldError(r.stderr.strip().removeprefix("ev3-sim: ") or f"ev3-sim world {path}: exit {r.returncode}")
        return World.from_json(r.stdout, str(path))

    @staticmethod
    def from_json(text: str, origin: str) -> "World":
        def numbers(values, n: int) -> tuple:
            out = tuple(float(v) for v in values)
            if len(out) != n:
                raise ValueError(f"{len(out)} numbers where {n} belong")
            return out

        def polygon(points) -> list[Point]:
            out = [numbers(p, 2) for p in points]
            if len(out) < 3:
                raise ValueError(f"a polygon of {len(out)} points")
            return out

        try:
            d = json.loads(text)
            return World(bounds=numbers(d["bounds"], 4),
                         walls=[numbers(w, 4) for w in d["walls"]],
                         boxes=[polygon(b) for b in d["boxes"]],
                         patches=[(str(p["colour"]), polygon(p["poly"])) for p in d["patches"]],
                         starts=[numbers(s, 3) for s in d["starts"]])
        except (ValueError, KeyError, TypeError) as e:
            raise WorldError(f"{origin}: not the JSON of `ev3-sim world` ({type(e).__name__}: {e})") from None
