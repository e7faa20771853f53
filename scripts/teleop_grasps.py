"""Render where to grasp each object, per task, from the sim: docs/teleop_grasps_<task>.png.

    .venv/bin/python scripts/teleop_grasps.py [--task Square ...] [--out docs]

Each picture is the scene `skillgen demos record --task <task>` starts in (D0, seed 0), seen by a
pybullet camera (TinyRenderer, as the sim's own cameras), with every skill's working point
(core/tasks/skill_points.py: the point auto-annotation measures to) marked and labelled with its
offset from the object's origin, and an arrow from that origin to the point. The table in docs/teleop.md
gives the same points as offsets in the object frame.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

# The camera looks from behind the robot's base over the table, as the person at the keyboard thinks:
# up in the picture is +x (w), left is +y (a). The arm is left out of the picture so it hides nothing.
VIEW_OFFSET = np.array([-0.55, 0.0, 0.60])  # camera eye from the objects' centre


def skill_rows(task, poses) -> list[dict]:
    """One row per skill: index, object, keypoint name, offset in the object frame, world point."""
    from skillgen_ros.core.tasks.skill_points import skill_point_name, skill_point_offset, skill_point_world

    return [{"skill": sk.index, "name": sk.name, "object": sk.object_id, "point": skill_point_name(task, sk.index),
             "offset": skill_point_offset(task, sk.index),
             "world": skill_point_world(task, sk.index, poses[sk.object_id])} for sk in task.skills]


def project(K, T_world_camera, p) -> np.ndarray:
    """Pixel (u, v) of world point p (OpenCV convention, as CameraConfig.intrinsics)."""
    q = np.linalg.inv(T_world_camera) @ np.append(np.asarray(p, float), 1.0)
    return np.array([K[0, 0] * q[0] / q[2] + K[0, 2], K[1, 1] * q[1] / q[2] + K[1, 2]])


def render_task(name: str, out: Path, width: int = 1000, height: int = 640) -> tuple[Path, list[dict]]:
    """Write out/teleop_grasps_<name>.png; returns its path and the skill rows with their pixels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from skillgen_ros.core.sim import SimWorld
    from skillgen_ros.core.sim import camera as cam
    from skillgen_ros.core.tasks import get_task

    task = get_task(name)
    world = SimWorld()
    try:
        world.reset(name, "D0", 0)
        poses = world.object_poses()
        world.p.removeBody(world.robot)  # a picture of the scene only; the world is closed right after
        rows = skill_rows(task, poses)
        centre = np.mean([r["world"] for r in rows], axis=0)
        cfg = cam.CameraConfig("doc", width=width, height=height, fov_deg=50.0)
        T = cam.look_at(centre + VIEW_OFFSET, centre)
        frame = cam.render(world.p, cfg, T, np.random.default_rng(0))
    finally:
        world.close()
    K = cfg.intrinsics()
    fig, ax = plt.subplots(figsize=(width / 100, height / 100), dpi=100)
    ax.imshow(frame.rgb[..., :3])
    placed = []  # label centres (pixels) so far: a label near one drops below it (Coffee Prep's drawer and pod)
    for r in rows:
        r["pixel"] = project(K, T, r["world"])
        u, v = r["pixel"]
        ax.plot(u, v, "o", ms=11, mfc="none", mec="red", mew=2.5)
        off = ", ".join(f"{v:+.3f}" for v in r["offset"])
        left = u < width / 2  # labels point outward from the picture's centre line, so neighbours do not cross
        dy = -18  # points (1 point = 100/72 pixels at this dpi; pixels grow downward)
        while any(side == left and abs(pu - u) < 250 and abs(pv - (v - dy * 100 / 72)) < 52
                  for side, pu, pv in placed):
            dy -= 40
        placed.append((left, u, v - dy * 100 / 72))
        ax.annotate(f"skill {r['skill']} {r['name']}: {r['object']} {r['point']}\n"
                    f"offset ({off}) m", (u, v), xytext=(14 if not left else -14, dy),
                    textcoords="offset points", color="white", fontsize=9, ha="right" if left else "left",
                    bbox={"facecolor": "black", "alpha": 0.65, "pad": 2},
                    arrowprops={"arrowstyle": "-", "color": "white", "lw": 1} if dy < -18 else None)
        if np.linalg.norm(r["offset"]) > 0.01:  # from the object's origin to the point (yellow)
            o = project(K, T, poses[r["object"]].position)
            ax.annotate("", xy=(u, v), xytext=o, arrowprops={"arrowstyle": "->", "color": "yellow", "lw": 2})
    for xy, label in (((0.95, 0.22), "w: +x"), ((0.90, 0.06), "a: +y")):  # the key frame, bottom right
        ax.annotate("", xy=xy, xytext=(0.95, 0.06), xycoords="axes fraction", textcoords="axes fraction",
                    arrowprops={"arrowstyle": "->", "color": "black", "lw": 2})
        ax.text(xy[0] - 0.01, xy[1] + 0.01, label, transform=ax.transAxes, color="black", fontsize=10, ha="right",
                bbox={"facecolor": "white", "alpha": 0.8, "pad": 1})
    ax.set_axis_off()
    ax.set_title(f"{name} (D0, seed 0), seen from behind the robot: where the hand works on each skill's object "
                 "(offset: in the object's frame from its origin; yellow arrow: origin to point)", fontsize=9)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"teleop_grasps_{name}.png"
    fig.savefig(path, bbox_inches="tight", pad_inches=0.05)
    plt.close(fig)
    return path, rows


def main(argv=None) -> int:
    from skillgen_ros.core.tasks import TASK_NAMES

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--task", action="append", help=f"one of {list(TASK_NAMES)} (default: all)")
    p.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs"), help="output folder")
    a = p.parse_args(argv)
    for name in a.task or TASK_NAMES:
        path, rows = render_task(name, Path(a.out))
        print(path)
        for r in rows:
            print(f"  skill {r['skill']} {r['object']:11s} {r['point']:12s} offset "
                  f"{np.round(r['offset'], 4).tolist()} world {np.round(r['world'], 3).tolist()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
