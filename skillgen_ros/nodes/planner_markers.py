"""The planner's `planner/path_markers` (Foxglove): each segment's waypoint path and goal EE pose, and the
EE path of the timed trajectory, coloured by phase (retreat, transit/transfer, approach)."""
from __future__ import annotations

from geometry_msgs.msg import Point
from visualization_msgs.msg import Marker, MarkerArray

from skillgen_ros.core.geometry import Pose
from skillgen_ros.nodes import convert

COLOURS = {"retreat": (1.0, 0.6, 0.0), "transit": (0.1, 0.6, 1.0), "transfer": (0.7, 0.2, 1.0),
           "approach": (0.2, 0.9, 0.2)}


def path_markers(kin, result, stamp) -> MarkerArray:
    """The markers of one plan (a MotionPlanner result with segments, joint_path and trajectory)."""
    ee = kin.fk_batch(result.trajectory.positions)[:, :3, 3]
    wp_T = kin.fk_batch(result.joint_path)
    wp_ee = wp_T[:, :3, 3]
    arr = MarkerArray()
    arr.markers.append(Marker(action=Marker.DELETEALL))
    for i, (phase, a, b) in enumerate(result.segments):
        m = Marker(ns="planner_path", id=i, type=Marker.LINE_STRIP, action=Marker.ADD)
        m.header.frame_id, m.header.stamp = "world", stamp
        m.pose.orientation.w = 1.0
        m.scale.x = 0.005
        m.color.r, m.color.g, m.color.b = COLOURS.get(phase, (1.0, 1.0, 1.0))
        m.color.a = 1.0
        m.points = [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in wp_ee[a:b + 1]]
        arr.markers.append(m)
        g = Marker(ns="planner_goal", id=i, type=Marker.ARROW, action=Marker.ADD)  # the segment's goal EE
        g.header.frame_id, g.header.stamp = "world", stamp  # pose: the recorder makes it a TF frame
        g.pose = convert.pose_to_msg(Pose.from_matrix(wp_T[b]))
        g.scale.x, g.scale.y, g.scale.z = 0.06, 0.006, 0.006
        g.color.r, g.color.g, g.color.b = COLOURS.get(phase, (1.0, 1.0, 1.0))
        g.color.a = 1.0
        arr.markers.append(g)
    m = Marker(ns="planner_ee", id=100, type=Marker.LINE_STRIP, action=Marker.ADD)
    m.header.frame_id, m.header.stamp = "world", stamp
    m.pose.orientation.w = 1.0
    m.scale.x = 0.002
    m.color.r = m.color.g = m.color.b = m.color.a = 1.0
    m.points = [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in ee[:: max(1, len(ee) // 200)]]
    arr.markers.append(m)
    return arr
