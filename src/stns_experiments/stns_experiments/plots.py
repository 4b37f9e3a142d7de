"""Figures in the spirit of the paper (matplotlib, Agg backend, PNG)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import ListedColormap  # noqa: E402
from matplotlib.patches import Circle, Patch  # noqa: E402

BEHAVIOUR_NAMES = {0: "forward", 1: "backward", 2: "clockwise", 3: "counter-clockwise"}
BEHAVIOUR_GLYPH = {0: "\u2191", 1: "\u2193", 2: "\u21bb", 3: "\u21ba"}


def curve_figure(path: Path, series: Sequence[dict], title: str, block_size: int,
                 paper_level: float | None = None, paper_label: str = "paper",
                 xlabel: str = "behaviour steps", ylabel: str = "behaviours to goal",
                 ylog: bool = True, vlines: Sequence[tuple[float, str]] = ()) -> Path:
    """Behaviours to goal by block: one line per series, optional inter-quartile band.

    Each series: {"label", "y" (per block), optional "lo"/"hi" (band), optional "offset"
    (steps added to the x axis), optional "style"}.
    """
    fig, ax = plt.subplots(figsize=(7.0, 4.2), dpi=110)
    for s in series:
        y = np.asarray(s["y"], dtype=float)
        x = (np.arange(len(y)) + 1) * block_size + s.get("offset", 0)
        line, = ax.plot(x, y, s.get("style", "-"), lw=1.6, label=s["label"])
        if s.get("lo") is not None and s.get("hi") is not None:
            ax.fill_between(x, np.asarray(s["lo"], float), np.asarray(s["hi"], float),
                            color=line.get_color(), alpha=0.18, lw=0)
    if paper_level is not None:
        ax.axhline(paper_level, color="k", ls=":", lw=1.0, label=paper_label)
    for xv, lab in vlines:
        ax.axvline(xv, color="grey", ls="--", lw=0.9)
        ax.text(xv, ax.get_ylim()[1], f" {lab}", va="top", ha="left", fontsize=8, color="grey")
    if ylog:
        ax.set_yscale("log")
        ax.set_yticks([1, 2, 3, 5, 10, 20, 50, 100])
        ax.get_yaxis().set_major_formatter(matplotlib.ticker.ScalarFormatter())
        ax.get_yaxis().set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_ylim(1, None)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel + f" (blocks of {block_size})")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return Path(path)


def _palette(n: int) -> list:
    base = plt.get_cmap("tab20").colors
    return [base[i % len(base)] for i in range(n)]


def situation_labels(grid: np.ndarray, situations: Sequence[dict]) -> dict[int, str]:
    """The legend of a situation map, by id (the margin, 0, left out): kind, condition
    behaviour and a T-situation's parent. A situation that wins no cell of the map (bitten
    away there, or behind others) says so, since its colour is nowhere to be seen."""
    on_map = {int(v) for v in np.unique(grid)}
    by_id = {s["id"]: s for s in situations}
    labels = {}
    for sid in sorted((on_map | set(by_id)) - {0}):
        s = by_id.get(sid, {})
        b = s.get("behaviour")
        lab = f"{sid}: {s.get('kind', '?')} {BEHAVIOUR_GLYPH.get(b, '?')} {BEHAVIOUR_NAMES.get(b, '')}"
        if s.get("kind") == "T" and s.get("parent") is not None:
            lab += f" -> {s['parent']}"
        labels[sid] = lab if sid in on_map else lab + " (nowhere on this map)"
    return labels


def situation_map(path: Path, classify: Callable[[np.ndarray], int], situations: Sequence[dict],
                  title: str, extent: float = 115.0, resolution: int = 161,
                  goal_radius: float = 5.0, max_distance: float | None = 112.0) -> Path:
    """The goal-sensor space (x forward, y left) coloured by situation (Fig. 5, 7, 9).

    White = situation 0 (margin space). The legend gives each situation's kind and condition
    behaviour, T-situations with their parent.
    """
    xs = np.linspace(-extent, extent, resolution)
    grid = np.zeros((resolution, resolution), dtype=np.int64)
    for i, y in enumerate(xs):
        for j, x in enumerate(xs):
            grid[i, j] = classify(np.array([x, y]))
    labels = situation_labels(grid, situations)
    ids = list(labels)
    colors = [(1, 1, 1)] + _palette(len(ids))
    lut = {0: 0} | {sid: k + 1 for k, sid in enumerate(ids)}
    img = np.vectorize(lambda v: lut.get(int(v), 0))(grid)
    fig, ax = plt.subplots(figsize=(6.4, 5.6), dpi=110)
    ax.imshow(img, origin="lower", extent=(-extent, extent, -extent, extent),
              cmap=ListedColormap(colors), vmin=0, vmax=len(colors) - 1, interpolation="nearest")
    ax.add_patch(Circle((0, 0), goal_radius, fill=False, color="k", lw=1.2))
    if max_distance:
        ax.add_patch(Circle((0, 0), max_distance, fill=False, color="grey", lw=0.8, ls="--"))
    by_id = {s["id"]: s for s in situations}
    handles = []
    for sid in ids:
        b = by_id.get(sid, {}).get("behaviour")
        handles.append(Patch(color=colors[lut[sid]], label=labels[sid]))
        pts = np.argwhere(grid == sid)
        if len(pts):
            cy, cx = pts.mean(axis=0)
            ax.text(xs[int(round(cx))], xs[int(round(cy))], f"{sid}{BEHAVIOUR_GLYPH.get(b, '')}",
                    ha="center", va="center", fontsize=8)
    ax.set_xlabel("goal x in the rover frame (forward), u")
    ax.set_ylabel("goal y (left), u")
    ax.set_title(title, fontsize=10)
    if handles:
        ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)
    return Path(path)


def workspace_map(path: Path, world, classify: Callable[[np.ndarray], int],
                  situations: Sequence[dict], theta: float, title: str,
                  resolution: int = 61) -> Path:
    """Exp. 3 (Fig. 12): rover positions in the room at a fixed attitude, coloured by the
    situation their 8-D input falls in (computed with the world's reset at a given pose)."""
    cfg = world.config
    size = cfg.room_size
    xs = np.linspace(0, size, resolution)
    grid = np.full((resolution, resolution), -1, dtype=np.int64)
    goal = world.goal
    for i, y in enumerate(xs):
        for j, x in enumerate(xs):
            try:
                obs, _ = world.reset(options={"pose": (x, y, theta), "goal": goal})
            except Exception:  # noqa: BLE001 - poses inside walls/obstacles stay blank
                continue
            grid[i, j] = classify(obs)
    ids = sorted({int(v) for v in np.unique(grid)} - {0, -1})
    colors = [(0.35, 0.35, 0.35), (1, 1, 1)] + _palette(len(ids))
    lut = {-1: 0, 0: 1} | {sid: k + 2 for k, sid in enumerate(ids)}
    img = np.vectorize(lambda v: lut.get(int(v), 1))(grid)
    fig, ax = plt.subplots(figsize=(6.4, 5.6), dpi=110)
    ax.imshow(img, origin="lower", extent=(0, size, 0, size), cmap=ListedColormap(colors),
              vmin=0, vmax=len(colors) - 1, interpolation="nearest")
    for box in getattr(cfg, "obstacles", ()):
        x0, y0, x1, y1 = box.bounds
        ax.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, color="k", alpha=0.6))
    ax.add_patch(Circle(goal, cfg.goal_radius, fill=False, color="r", lw=1.5))
    by_id = {s["id"]: s for s in situations}
    handles = []
    for sid in ids:
        s = by_id.get(sid, {})
        b = s.get("behaviour")
        lab = f"{sid}: {s.get('kind', '?')} {BEHAVIOUR_GLYPH.get(b, '?')} {BEHAVIOUR_NAMES.get(b, '')}"
        handles.append(Patch(color=colors[lut[sid]], label=lab))
    ax.set_title(title + f" (attitude {np.degrees(theta):.0f} deg)", fontsize=10)
    ax.set_xlabel("x, u")
    ax.set_ylabel("y, u")
    if handles:
        ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)
    return Path(path)


def panel_figure(path: Path, panels: Sequence[dict], title: str, block_size: int,
                 xlabel: str = "behaviour steps after the fault") -> Path:
    """Several relearn-vs-scratch panels side by side (Fig. 8 / Fig. 10 layout).

    Each panel: {"title", "series": [curve_figure series], "level": optional line}.
    """
    n = len(panels)
    cols = min(3, n)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.2 * rows), dpi=100,
                             squeeze=False, sharey=True)
    for ax, panel in zip(axes.flat, panels, strict=False):
        for s in panel["series"]:
            y = np.asarray(s["y"], dtype=float)
            x = (np.arange(len(y)) + 1) * block_size
            line, = ax.plot(x, y, s.get("style", "-"), lw=1.4, label=s["label"])
            if s.get("lo") is not None and s.get("hi") is not None:
                ax.fill_between(x, np.asarray(s["lo"], float), np.asarray(s["hi"], float),
                                color=line.get_color(), alpha=0.18, lw=0)
        if panel.get("level") is not None:
            ax.axhline(panel["level"], color="k", ls=":", lw=1.0, label="pre-fault level")
        ax.set_yscale("log")
        ax.set_yticks([1, 2, 3, 5, 10, 20, 50])
        ax.get_yaxis().set_major_formatter(matplotlib.ticker.ScalarFormatter())
        ax.get_yaxis().set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_ylim(1.5, 60)
        ax.set_title(panel["title"], fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.set_xlabel(xlabel, fontsize=8)
    for ax in axes.flat[n:]:
        ax.axis("off")
    axes.flat[0].set_ylabel(f"behaviours to goal (blocks of {block_size})", fontsize=8)
    axes.flat[0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return Path(path)
