#!/usr/bin/env python3
"""Figures of a localization run against the mapped poses (numpy only).

  localization_errors.py initial MAPPED.txt FRAME DX DY DZ DYAW_DEG
      the mapped pose of FRAME moved by (DX, DY, DZ) m and turned DYAW_DEG about the map's z axis, as the
      "x y z roll pitch yaw" aloam_offline --initial-pose takes
  localization_errors.py compare MAPPED.txt LOCALIZED.txt START LOG.txt FROM_ANSWER
      errors of the localized poses (frames START on) against the mapped ones, from the FROM_ANSWER-th
      answered frame on; prints `key: value` figures
  localization_errors.py same_map A.pcd B.pcd
      whether two binary map PCDs (x y z label) hold the same points, in any order
"""
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts"))
from aloam_poses import read_kitti  # noqa: E402


def rpy(r):
    return (math.atan2(r[2, 1], r[2, 2]), math.asin(max(-1.0, min(1.0, -r[2, 0]))), math.atan2(r[1, 0], r[0, 0]))


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def initial(args):
    mapped = read_kitti(args[0])[int(args[1])]
    dx, dy, dz, dyaw = (float(v) for v in args[2:6])
    r = rot_z(math.radians(dyaw)).dot(mapped[:3, :3])
    t = mapped[:3, 3] + np.array([dx, dy, dz])
    print("%.6f %.6f %.6f %.6f %.6f %.6f" % ((t[0], t[1], t[2]) + rpy(r)))


def compare(args):
    mapped = read_kitti(args[0])
    localized = read_kitti(args[1])
    start = int(args[2])
    rows = [line.split() for line in open(args[3]) if not line.startswith("#")]
    from_answer = int(args[4])
    answered = [row[2] == "1" for row in rows]
    states = [row[3] for row in rows]
    trans, rot = [], []
    count = 0
    for i, pose in enumerate(localized):
        if not answered[i]:
            continue
        count += 1
        if count < from_answer:
            continue
        truth = mapped[start + i]
        trans.append(float(np.linalg.norm(pose[:3, 3] - truth[:3, 3])))
        d = truth[:3, :3].T.dot(pose[:3, :3])
        rot.append(math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(d) - 1.0) / 2.0)))))
    print("frames: %d" % len(localized))
    print("answered: %d" % sum(answered))
    print("localized_frames: %d" % states.count("localized"))
    print("lost_frames: %d" % states.count("lost"))
    print("final_state: %s" % states[-1])
    first = next((i for i, s in enumerate(states) if s == "localized"), -1)
    print("first_localized_answer: %d" % (first + 1 if first >= 0 else -1))
    print("max_translation_error_m: %.4f" % (max(trans) if trans else float("nan")))
    print("max_rotation_error_deg: %.4f" % (max(rot) if rot else float("nan")))
    print("rmse_translation_m: %.4f" % (math.sqrt(sum(e * e for e in trans) / len(trans)) if trans else float("nan")))


def read_map(path):
    """The points of a binary PCD of x y z label (as aloam's map files), sorted."""
    with open(path, "rb") as f:
        header = {}
        while True:
            line = f.readline().decode("ascii").split()
            if line:
                header[line[0]] = line[1:]
            if line and line[0] == "DATA":
                break
        if header["FIELDS"] != ["x", "y", "z", "label"] or header["DATA"] != ["binary"]:
            raise SystemExit("%s: not a binary x y z label PCD" % path)
        points = np.frombuffer(f.read(), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("label", "<u4")])
    return np.sort(points, order=["x", "y", "z", "label"])


def same_map(args):
    a, b = read_map(args[0]), read_map(args[1])
    print("points: %d %d" % (len(a), len(b)))
    print("same_points: %s" % ("yes" if len(a) == len(b) and a.tobytes() == b.tobytes() else "no"))


if __name__ == "__main__":
    {"initial": initial, "compare": compare, "same_map": same_map}[sys.argv[1]](sys.argv[2:])
