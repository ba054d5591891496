"""The map: the world (when there is one) and each robot's path from its odometry reports
(SENSOR_VALUE pose ODOM x_mm y_mm heading_deg), its last pose drawn as an arrow."""

from __future__ import annotations

import math

from .world import COLOURS, World

PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22"]


def poses(db) -> dict[int, list[tuple[float, float, float]]]:
    """Per robot, its odometry poses in order: (x cm, y cm, heading degrees)."""
    out: dict[int, list[tuple[float, float, float]]] = {}
    if db is None:
        return out
    for agent, text in db.execute("SELECT agent, text FROM reports WHERE type = 'SENSOR_VALUE' "
                                  "AND text LIKE 'pose:%' ORDER BY agent, coalesce(seq, 0), rowid"):
        f = text.split(":")
        try:
            out.setdefault(agent, []).append((float(f[2]) / 10, float(f[3]) / 10, float(f[4])))
        except (IndexError, ValueError):
            continue
    return out


def map_figure(db, world: World | None):
    from matplotlib.figure import Figure  # the object API: no global state, safe in a worker thread
    from matplotlib.patches import Polygon, Rectangle
    fig = Figure(figsize=(7, 5.25))
    ax = fig.subplots()
    if world is not None:
        x0, y0, x1, y1 = world.bounds
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, linewidth=2, edgecolor="#444444"))
        for colour, poly in world.patches:
            ax.add_patch(Polygon(poly, closed=True, facecolor=COLOURS.get(colour, "#cccccc"), alpha=0.5,
                                 edgecolor="none"))
        for box in world.boxes:
            ax.add_patch(Polygon(box, closed=True, facecolor="#777777", edgecolor="#333333"))
        for xa, ya, xb, yb in world.walls:
            ax.plot([xa, xb], [ya, yb], color="#333333", linewidth=3)
        ax.set_xlim(x0 - 5, x1 + 5)
        ax.set_ylim(y0 - 5, y1 + 5)
    paths = poses(db)
    for i, (agent, pts) in enumerate(sorted(paths.items())):
        colour = PALETTE[i % len(PALETTE)]
        ax.plot([p[0] for p in pts], [p[1] for p in pts], color=colour, linewidth=1.2, label=f"robot {agent}")
        x, y, h = pts[-1]
        ax.annotate("", xy=(x + 12 * math.cos(math.radians(h)), y + 12 * math.sin(math.radians(h))), xytext=(x, y),
                    arrowprops={"arrowstyle": "-|>", "color": colour, "linewidth": 2})
        ax.text(x + 4, y + 4, str(agent), color=colour, fontsize=10, fontweight="bold")
    if paths:
        ax.legend(loc="upper right", fontsize=8)
    else:
        ax.text(0.5, 0.5, "no pose reports yet", transform=ax.transAxes, ha="center", color="#888888")
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    ax.grid(alpha=0.2)
    fig.tight_layout()
    return fig
