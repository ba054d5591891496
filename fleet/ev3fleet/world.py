"""An ev3-sim world file (docs/devices.md "The world file") read for drawing: its bounds, walls,
boxes, floor patches and start poses, in centimetres. ev3-sim checks the file; this reader takes
what it draws and names the line of anything it cannot read."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

COLOURS = {"none": "#ffffff", "black": "#222222", "blue": "#3b6fd8", "green": "#3fa34d", "yellow": "#f2d21b",
           "red": "#d83b3b", "white": "#f4f4f4", "brown": "#8b5a2b"}


class WorldError(ValueError):
    """A world file this reader cannot draw (the message names the file and line)."""


@dataclass
class World:
    bounds: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    walls: list[tuple[float, float, float, float]] = field(default_factory=list)
    boxes: list[tuple[float, float, float, float]] = field(default_factory=list)
    patches: list[tuple[str, list[tuple[float, float]]]] = field(default_factory=list)  # colour, polygon
    starts: list[tuple[float, float, float]] = field(default_factory=list)

    @staticmethod
    def read(path: Path) -> "World":
        try:
            text = Path(path).read_text()
        except OSError as e:
            raise WorldError(f"{path}: {e.strerror}") from None
        w = World()
        has_bounds = False
        for n, raw in enumerate(text.splitlines(), 1):
            words = raw.split("#", 1)[0].split()
            if not words:
                continue
            try:
                kind, args = words[0], words[1:]
                if kind == "bounds":
                    w.bounds = tuple(numbers(args, 4))
                    has_bounds = True
                elif kind == "wall":
                    w.walls.append(tuple(numbers(args, 4)))
                elif kind == "box":
                    w.boxes.append(tuple(numbers(args, 4)))
                elif kind == "start":
                    w.starts.append(tuple(numbers(args, 3)))
                elif kind == "floor":
                    colour, shape, rest = args[0], args[1], args[2:]
                    if "reflect" in rest:
                        rest = rest[:rest.index("reflect")]
                    if shape == "rect":
                        x, y, wd, ht = numbers(rest, 4)
                        poly = [(x, y), (x + wd, y), (x + wd, y + ht), (x, y + ht)]
                    elif shape == "poly" and len(rest) >= 6 and len(rest) % 2 == 0:
                        v = numbers(rest, len(rest))
                        poly = list(zip(v[0::2], v[1::2]))
                    else:
                        raise ValueError(f"a floor patch is 'rect X Y W H' or 'poly X1 Y1 ...', not '{shape}'")
                    w.patches.append((colour, poly))
                elif kind not in ("units", "ground"):
                    raise ValueError(f"unknown statement '{kind}'")
            except (ValueError, IndexError) as e:
                raise WorldError(f"{path} line {n}: {e or 'too few words'}") from None
        if not has_bounds:
            raise WorldError(f"{path}: no 'bounds' line")
        return w


def numbers(words: list[str], n: int) -> list[float]:
    if len(words) != n:
        raise ValueError(f"expected {n} numbers, got {len(words)}")
    return [float(x) for x in words]
