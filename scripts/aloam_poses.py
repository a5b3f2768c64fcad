"""Pose helpers shared by the demo report, the rostests and the hard-case checks (numpy only)."""
import math

import numpy as np


def quat_to_rot(x, y, z, w):
    """Rotation matrix of a quaternion (normalized first)."""
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def read_kitti(path):
    """The 4x4 poses of a KITTI pose file (3x4 rows), as an (N, 4, 4) array; other lines are skipped."""
    rows = [values for values in (line.split() for line in open(path)) if len(values) == 12]
    poses = np.tile(np.eye(4), (len(rows), 1, 1))
    if rows:
        poses[:, :3, :] = np.array(rows, dtype=float).reshape(-1, 3, 4)
    return poses


def write_kitti(path, poses):
    """Writes 4x4 poses as KITTI 3x4 rows."""
    with open(path, "w") as out:
        for m in poses:
            out.write(" ".join("%.9e" % v for v in m[:3, :].reshape(-1)) + "\n")
