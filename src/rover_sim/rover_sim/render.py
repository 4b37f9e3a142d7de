"""Top-down pictures of the world (PNG via matplotlib's Agg canvas, no pyplot state)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon, Rectangle, Wedge

from rover_sim.config import WorldConfig
from rover_sim.errors import RoverSimError
from rover_sim.geometry import rover_corners
from rover_sim.sensors import N_SECTORS, SECTOR_NAMES, sector_bounds
from rover_sim.world import RoverWorld


def render_topdown(
    world_or_config: RoverWorld | WorldConfig,
    trajectory: Sequence[Sequence[float]] | np.ndarray | None,
    path: str | Path,
    *,
    goal: tuple[float, float] | None = None,
    pose: tuple[float, float, float] | None = None,
    show_sectors: bool = False,
    title: str | None = None,
    dpi: int = 100,
) -> Path:
    """Draw room, obstacles, goal, rover and trajectory to a PNG at `path`.

    `trajectory` is a sequence of (x, y) or (x, y, theta) in u (may be empty or None).
    From a `RoverWorld` the goal and rover pose default to the world's; from a
    `WorldConfig` to the config's fixed goal (if any) and the trajectory's last pose.
    `show_sectors` draws the six range-sensor sectors around the rover (with the
    readings when a world is given). Returns the path written.
    """
    if isinstance(world_or_config, RoverWorld):
        world: RoverWorld | None = world_or_config
        config = world_or_config.config
    elif isinstance(world_or_config, WorldConfig):
        world, config = None, world_or_config
    else:
        raise RoverSimError(
            f"render_topdown needs a RoverWorld or WorldConfig, got {world_or_config!r}"
        )
    traj = np.empty((0, 2)) if trajectory is None else np.asarray(trajectory, dtype=float)
    if traj.size and (traj.ndim != 2 or traj.shape[1] not in (2, 3)):
        raise RoverSimError(f"trajectory must be N x 2 or N x 3, got shape {traj.shape!r}")
    if goal is None:
        goal = world.goal if world is not None else config.goal
    if pose is None:
        if world is not None:
            pose = world.pose
        elif traj.size and traj.shape[1] == 3:
            pose = tuple(traj[-1])

    size = config.room_size
    fig = Figure(figsize=(6, 6), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ax.add_patch(Rectangle((0, 0), size, size, fill=False, lw=3, ec="black"))
    if config.goal is None:
        lo = (size - config.goal_region) / 2
        ax.add_patch(
            Rectangle(
                (lo, lo),
                config.goal_region,
                config.goal_region,
                fill=False,
                ls=":",
                ec="tab:green",
                lw=1,
                label=f"goal region {config.goal_region:g}^2",
            )
        )
    for i, box in enumerate(config.obstacles):
        xmin, ymin, _, _ = box.bounds
        ax.add_patch(
            Rectangle(
                (xmin, ymin),
                box.sx,
                box.sy,
                fc="dimgray",
                ec="black",
                label="obstacle" if i == 0 else None,
            )
        )
    if goal is not None:
        ax.add_patch(
            Circle(
                goal,
                config.goal_radius,
                fc="tab:green",
                alpha=0.8,
                zorder=3,
                label=f"goal (r={config.goal_radius:g})",
            )
        )
    if traj.size:
        ax.plot(traj[:, 0], traj[:, 1], "-", color="tab:blue", lw=1, label="trajectory")
    if pose is not None:
        x, y, th = pose
        if show_sectors:
            ranges = world.range_readings() if world is not None else None
            for k in range(N_SECTORS):
                a0, a1 = sector_bounds(k)
                r = 30.0 if ranges is None else float(ranges[k])
                ax.add_patch(
                    Wedge(
                        (x, y),
                        r,
                        math.degrees(th + a0),
                        math.degrees(th + a1),
                        fc=f"C{k}",
                        alpha=0.25,
                        ec=f"C{k}",
                    )
                )
                mid = th + (a0 + a1) / 2
                label = f"{k} {SECTOR_NAMES[k]}"
                if ranges is not None:
                    label += f"\n{r:.1f} u"
                ax.text(
                    x + 0.6 * r * math.cos(mid),
                    y + 0.6 * r * math.sin(mid),
                    label,
                    ha="center",
                    va="center",
                    fontsize=8,
                )
        corners = rover_corners(pose, config.rover_length, config.rover_width)
        ax.add_patch(
            Polygon(corners, closed=True, fc="tab:orange", ec="black", alpha=0.7, label="rover")
        )
        ax.annotate(
            "",
            xy=(x + 10 * math.cos(th), y + 10 * math.sin(th)),
            xytext=(x, y),
            arrowprops={"arrowstyle": "->", "lw": 1.5},
        )
    ax.set_xlim(-5, size + 5)
    ax.set_ylim(-5, size + 5)
    ax.set_aspect("equal")
    ax.set_xlabel("x [u]  (1 u = 1/16 m)")
    ax.set_ylabel("y [u]")
    ax.set_title(title or f"{config.task}: room {size:g} x {size:g} u")
    ax.legend(loc="upper left", fontsize=7, framealpha=0.8)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    return out


def write_doc_pictures(out_dir: str | Path, seed: int = 0) -> list[Path]:
    """The README's pictures: sector layout, Exp. 3 layout, an Exp. 1 random run."""
    from rover_sim.config import WorldConfig as _Config

    out = Path(out_dir)
    paths = []
    with RoverWorld(_Config.preset("exp1"), seed=seed) as world:
        world.reset(options={"goal": (75.0, 70.0), "pose": (40.0, 45.0, math.radians(20))})
        paths.append(
            render_topdown(
                world,
                None,
                out / "sectors.png",
                show_sectors=True,
                title="Six range sectors (readings in u), rover at (40, 45), 20 deg",
            )
        )
    with RoverWorld(_Config.preset("exp3"), seed=seed) as world:
        world.reset(options={"pose": (30.0, 44.0, 0.0)})
        paths.append(
            render_topdown(
                world,
                None,
                out / "exp3_layout.png",
                show_sectors=True,
                title="Exp. 3: obstacle 8 x 24 at (55, 50), goal (80, 50)",
            )
        )
    with RoverWorld(_Config.preset("exp1"), seed=seed) as world:
        world.reset()
        policy = np.random.default_rng([seed, 1])
        poses = [world.pose]
        for _ in range(40):
            res = world.run_behaviour(int(policy.integers(4)), record=True)
            poses.extend(res.poses)
            if "collision" in res.events and world.config.post_collision == "replace":
                poses.insert(-1, (float("nan"),) * 3)  # no line to the re-placed pose
            if res.terminated:
                break
        paths.append(
            render_topdown(
                world,
                poses,
                out / "exp1_random.png",
                title=f"Exp. 1: random behaviours until the goal ({len(poses)} ticks)",
            )
        )
    return paths


if __name__ == "__main__":
    import sys

    for p in write_doc_pictures(sys.argv[1] if len(sys.argv) > 1 else "docs"):
        print(p)
