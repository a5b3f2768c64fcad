"""Shared helpers of the aloam_nodelet rostests (imported by the test_*.py nodes beside it; not a test).

- the package's tools (make_test_bag, aloam_eval, aloam_offline, replay_kitti.py) and the KITTI folder
- a numpy ray-caster of a small street (ground, two house rows with recesses, poles, an end wall) that
  produces VLP-16-like sweeps with per-point ring and time, from a moving or a resting sensor
- a LOAM-style feature extractor (curvature, sectors, sharp / flat picking) to build the stage messages
  aloam_nodelet/FeatureClouds and aloam_nodelet/OdometryFrame without the nodelets that normally make them
- PointCloud2 packing, unpacking and validation, pose and trajectory helpers, aloam_eval parsing
- a frame-by-frame replayer that publishes a sweep and waits for its answer on aft_mapped_to_init
- aloam_sim sequences: generation, their ground truth, playback, evaluation and /diagnostics figures
"""
import math
import os
import re
import shutil
import signal
import subprocess
import tempfile
import threading
import time
import sys
import unittest

import numpy as np
import rosgraph
import rospkg
import rospy
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from sensor_msgs.msg import PointCloud2, PointField

# The pose helpers the demo report uses too (scripts/aloam_poses.py).
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts"))
from aloam_poses import quat_to_rot  # noqa: E402,F401 (re-exported for the tests)

PKG = "aloam_nodelet"
VIS_FIELDS = ("x", "y", "z", "intensity", "time", "ring")

# --------------------------------------------------------------------------------------------------------
# Locations


def package_dir():
    return rospkg.RosPack().get_path(PKG)


def devel_tool(name):
    """Path of an executable built into devel/lib/aloam_nodelet (make_test_bag, aloam_eval, ...)."""
    from catkin.find_in_workspaces import find_in_workspaces
    found = find_in_workspaces(["libexec"], project=PKG, path=name, first_match_only=True)
    if not found or not os.access(found[0], os.X_OK):
        raise RuntimeError("%s not found in the catkin workspaces (build the package first)" % name)
    return found[0]


def kitti_candidates():
    """Where the KITTI 00 frames 0-100 folder may be: $ALOAM_DATA/kitti00_101, then <repo>/../shared/data."""
    candidates = []
    if os.environ.get("ALOAM_DATA"):
        candidates.append(os.path.join(os.environ["ALOAM_DATA"], "kitti00_101"))
    repo = os.path.realpath(package_dir())
    candidates.append(os.path.join(os.path.dirname(repo), "shared", "data", "kitti00_101"))
    return candidates


def kitti_dir():
    """The first KITTI folder of kitti_candidates() with velodyne/ and the ground truth, None if absent."""
    for path in kitti_candidates():
        if os.path.isdir(os.path.join(path, "velodyne")) and os.path.isfile(os.path.join(path, "poses_kitti_gt.txt")):
            return path
    return None


class ScratchTestCase(unittest.TestCase):
    """A test case with a scratch directory, removed when every test passed, kept (and named) otherwise."""

    @classmethod
    def setUpClass(cls):
        cls.scratch = tempfile.mkdtemp(prefix="aloam_rostest_%s_" % cls.__name__)
        cls._failed = False
        cls._t0 = time.time()

    @classmethod
    def tearDownClass(cls):
        print("[%s] %.1f s in the test node" % (cls.__name__, time.time() - cls._t0), flush=True)
        if cls._failed or os.environ.get("ALOAM_KEEP_TEST_OUTPUT"):
            print("[%s] test output kept in %s" % (cls.__name__, cls.scratch), flush=True)
        else:
            shutil.rmtree(cls.scratch, ignore_errors=True)

    def run(self, result=None):
        result = result if result is not None else self.defaultTestResult()
        before = len(result.failures) + len(result.errors)
        out = super().run(result)
        if len(result.failures) + len(result.errors) > before:
            type(self)._failed = True
        return out

    def path(self, name):
        return os.path.join(self.scratch, name)


def stop_launch(process):
    """Stops a roslaunch started in a session of its own: SIGINT to its group, SIGKILL after 30 s."""
    if process is None or process.poll() is not None:
        return
    os.killpg(process.pid, signal.SIGINT)
    try:
        process.wait(timeout=30)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)


# --------------------------------------------------------------------------------------------------------
# ROS graph


def topic_state(name):
    """(publisher nodes, subscriber nodes) of a topic, from the master."""
    pubs, subs, _ = rosgraph.Master("/aloam_rostest").getSystemState()
    return ([n for t, nodes in pubs if t == name for n in nodes],
            [n for t, nodes in subs if t == name for n in nodes])


def wait_for_graph(subscribed=(), published=(), timeout=30.0):
    """Waits until every topic in `subscribed` has a subscriber and every one in `published` a publisher."""
    deadline = time.time() + timeout
    missing = list(subscribed) + list(published)
    while time.time() < deadline and not rospy.is_shutdown():
        missing = [t for t in subscribed if not topic_state(t)[1]] + [t for t in published if not topic_state(t)[0]]
        if not missing:
            return []
        time.sleep(0.1)
    return missing


def wait_connected(endpoint, timeout=15.0):
    """Waits until a rospy Publisher or Subscriber has a connection."""
    deadline = time.time() + timeout
    while endpoint.get_num_connections() == 0 and time.time() < deadline and not rospy.is_shutdown():
        time.sleep(0.05)
    return endpoint.get_num_connections() > 0


def connected_collectors(test, topics):
    """A StampCollector for each {topic: type}, asserting (on `test`) that each gets a connection."""
    collectors = {t: StampCollector(t, ty) for t, ty in topics.items()}
    for t, c in collectors.items():
        test.assertTrue(wait_connected(c.sub), "no connection on %s" % t)
    return collectors


def wait_for_service(name, timeout=30.0):
    try:
        rospy.wait_for_service(name, timeout)
        return True
    except rospy.ROSException:
        return False


class StampCollector:
    """Keeps every message of a topic by stamp (nanoseconds), with arrival times, and waits for stamps."""

    def __init__(self, topic, msg_type, queue_size=100, keep=True):
        self.topic = topic
        self.keep = keep
        self.by_stamp = {}
        self.arrivals = []  # (wall time, stamp ns)
        self.count = 0
        self._cv = threading.Condition()
        self.sub = rospy.Subscriber(topic, msg_type, self._cb, queue_size=queue_size, buff_size=2 ** 26)

    def _cb(self, msg):
        with self._cv:
            stamp = msg.header.stamp.to_nsec()
            self.by_stamp[stamp] = msg if self.keep else True
            self.arrivals.append((time.time(), stamp))
            self.count += 1
            self._cv.notify_all()

    def wait_for(self, stamp_ns, timeout):
        with self._cv:
            self._cv.wait_for(lambda: stamp_ns in self.by_stamp or rospy.is_shutdown(), timeout)
            return self.by_stamp.get(stamp_ns)

    def wait_count(self, count, timeout):
        with self._cv:
            self._cv.wait_for(lambda: self.count >= count or rospy.is_shutdown(), timeout)
            return self.count

    def stamps(self):
        with self._cv:
            return [s for _, s in self.arrivals]

    def unregister(self):
        self.sub.unregister()


# --------------------------------------------------------------------------------------------------------
# Poses and trajectories


def rot_to_quat(r):
    """(x, y, z, w) of a rotation matrix."""
    t = np.trace(r)
    if t > 0:
        s = math.sqrt(t + 1.0) * 2
        return ((r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s)
    i = int(np.argmax(np.diag(r)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = math.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k]) * 2
    q = [0.0, 0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (r[j, i] + r[i, j]) / s
    q[k] = (r[k, i] + r[i, k]) / s
    q[3] = (r[k, j] - r[j, k]) / s
    return tuple(q)


def pose_to_matrix(pose):
    """4x4 matrix of a geometry_msgs/Pose."""
    p, q = pose.position, pose.orientation
    m = np.eye(4)
    m[:3, :3] = quat_to_rot(q.x, q.y, q.z, q.w)
    m[:3, 3] = [p.x, p.y, p.z]
    return m


def matrix_to_pose(m, pose):
    """Fills a geometry_msgs/Pose from a 4x4 matrix."""
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in m[:3, 3])
    x, y, z, w = rot_to_quat(m[:3, :3])
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = x, y, z, w
    return pose


def rot_z(yaw):
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def pose_is_finite(odom):
    p, q = odom.pose.pose.position, odom.pose.pose.orientation
    values = [p.x, p.y, p.z, q.x, q.y, q.z, q.w]
    return all(math.isfinite(v) for v in values) and abs(math.sqrt(sum(v * v for v in values[3:])) - 1.0) < 1e-3


def write_kitti(path, matrices, relative=True):
    """KITTI pose rows (3x4), relative to the first matrix when `relative`."""
    first_inv = np.linalg.inv(matrices[0]) if relative else np.eye(4)
    with open(path, "w") as out:
        for m in matrices:
            rel = first_inv @ m
            out.write(" ".join("%.9e" % v for v in rel[:3, :].reshape(-1)) + "\n")


def read_kitti(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line.strip():
                m = np.eye(4)
                m[:3, :] = np.array([float(v) for v in line.split()]).reshape(3, 4)
                rows.append(m)
    return rows


def run_eval(gt, trajectory, segments="5,10,20", extra=()):
    """Runs aloam_eval; returns ({metric: value}, full output)."""
    cmd = [devel_tool("aloam_eval"), "--gt", gt, "--trajectory", trajectory, "--segments", segments] + list(extra)
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True, timeout=120)
    metrics = {}
    for line in proc.stdout.splitlines():
        m = re.match(r"^\s*([a-z_%/0-9]+)\s*:\s*([-+0-9.eE]+|nan|inf)\s*$", line)
        if m:
            metrics[m.group(1)] = float(m.group(2))
    if proc.returncode != 0:
        raise AssertionError("aloam_eval failed (%d):\n%s" % (proc.returncode, proc.stdout))
    return metrics, proc.stdout


def pcd_points(path):
    """The POINTS count of a PCD file's header (and checks the header is complete)."""
    with open(path, "rb") as f:
        header = {}
        for _ in range(20):
            line = f.readline().decode("ascii", "replace").strip()
            if not line or line.startswith("#"):
                continue
            key, _, value = line.partition(" ")
            header[key] = value
            if key == "DATA":
                break
    if "POINTS" not in header or "DATA" not in header:
        raise AssertionError("%s: not a PCD file (header %s)" % (path, header))
    return int(header["POINTS"]), header


# --------------------------------------------------------------------------------------------------------
# PointCloud2

_DTYPES = {PointField.INT8: "i1", PointField.UINT8: "u1", PointField.INT16: "i2", PointField.UINT16: "u2",
           PointField.INT32: "i4", PointField.UINT32: "u4", PointField.FLOAT32: "f4", PointField.FLOAT64: "f8"}
_CODES = {"f4": PointField.FLOAT32, "u2": PointField.UINT16, "f8": PointField.FLOAT64, "u1": PointField.UINT8}

POINT_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("time", "<f4"),
                        ("ring", "<u2")])


def cloud_message(points, stamp, frame_id="velodyne"):
    """PointCloud2 of a structured numpy array (little endian, packed)."""
    points = np.ascontiguousarray(points)
    msg = PointCloud2()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height = 1
    msg.width = int(points.shape[0])
    msg.fields = []
    for name in points.dtype.names:
        dt, offset = points.dtype.fields[name]
        msg.fields.append(PointField(name, offset, _CODES[dt.str.lstrip("<|")], 1))
    msg.is_bigendian = False
    msg.point_step = points.dtype.itemsize
    msg.row_step = msg.point_step * msg.width
    msg.is_dense = True
    msg.data = points.tobytes()
    return msg


def cloud_array(msg):
    """Structured numpy view of a PointCloud2 (every field of count 1)."""
    names, formats, offsets = [], [], []
    for f in msg.fields:
        names.append(f.name)
        formats.append((">" if msg.is_bigendian else "<") + _DTYPES[f.datatype])
        offsets.append(f.offset)
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": msg.point_step})
    return np.frombuffer(bytes(msg.data), dtype=dtype, count=msg.width * msg.height)


def cloud_problems(msg, fields=VIS_FIELDS, min_points=1):
    """Everything wrong with a PointCloud2 the nodelets wrote (empty list: well-formed)."""
    problems = []
    names = [f.name for f in msg.fields]
    if list(fields) != names[:len(fields)] and sorted(fields) != sorted(names):
        problems.append("fields %s, expected %s" % (names, list(fields)))
    if msg.width * msg.height * msg.point_step != len(msg.data):
        problems.append("width %d * height %d * point_step %d != %d data bytes"
                        % (msg.width, msg.height, msg.point_step, len(msg.data)))
    if msg.row_step != msg.width * msg.point_step:
        problems.append("row_step %d != width * point_step %d" % (msg.row_step, msg.width * msg.point_step))
    for f in msg.fields:
        if f.offset + np.dtype(_DTYPES[f.datatype]).itemsize * f.count > msg.point_step:
            problems.append("field %s beyond point_step" % f.name)
    if problems:
        return problems
    if msg.width * msg.height < min_points:
        problems.append("%d points, expected at least %d" % (msg.width * msg.height, min_points))
        return problems
    arr = cloud_array(msg)
    for name in ("x", "y", "z", "intensity", "time"):
        if name in arr.dtype.names and not np.all(np.isfinite(arr[name])):
            problems.append("non-finite %s values" % name)
    return problems


# --------------------------------------------------------------------------------------------------------
# A small synthetic street and a VLP-16-like ray-caster (numpy)

VLP16_ELEVATIONS_DEG = np.arange(-15.0, 15.1, 2.0)
SCAN_PERIOD = 0.1


class Street:
    """Ground z=0, house fronts at y=+7 and y=-8 with recessed doorways and protruding bays, poles every
    12 m on both sides, cross walls (an end wall at x=120 and kiosks across the street). Sensor 1.8 m up."""

    def __init__(self, seed=3, length=130.0):
        rng = np.random.RandomState(seed)
        self.planes = [  # (normal, offset): n.x = d
            (np.array([0.0, 0.0, 1.0]), 0.0),
            (np.array([0.0, 1.0, 0.0]), 7.0),
            (np.array([0.0, 1.0, 0.0]), -8.0),
            (np.array([1.0, 0.0, 0.0]), length - 10.0),
            (np.array([1.0, 0.0, 0.0]), -25.0),
        ]
        boxes = []
        x = -20.0
        while x < length - 15:
            w = rng.uniform(2.0, 4.0)
            depth = rng.uniform(0.6, 1.5)
            h = rng.uniform(2.5, 6.0)
            side = 1 if rng.rand() < 0.5 else -1
            wall = 7.0 if side > 0 else -8.0
            y0, y1 = sorted([wall, wall - side * depth])
            boxes.append((np.array([x, y0, 0.0]), np.array([x + w, y1, h])))
            x += w + rng.uniform(3.0, 8.0)
        # kiosks and parked-car-sized blocks near the kerbs
        for xc in np.arange(5.0, length - 20, 17.0):
            yc = 4.5 if rng.rand() < 0.5 else -5.5
            boxes.append((np.array([xc, yc - 0.9, 0.0]), np.array([xc + rng.uniform(1.5, 4.0), yc + 0.9, 1.5])))
        self.boxes_lo = np.array([b[0] for b in boxes])
        self.boxes_hi = np.array([b[1] for b in boxes])
        poles = []
        for xc in np.arange(-18.0, length - 12, 12.0):
            poles.append((xc + rng.uniform(-1, 1), 6.0, 0.15, 5.0))
            poles.append((xc + 6 + rng.uniform(-1, 1), -7.0, 0.15, 5.0))
        self.poles = np.array(poles)

    def cast(self, origins, dirs, max_range=100.0):
        """Ranges of rays (N x 3 origins, unit directions) to the first hit; inf where nothing is hit."""
        n = dirs.shape[0]
        best = np.full(n, np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            for normal, d in self.planes:
                den = dirs @ normal
                t = (d - origins @ normal) / den
                ok = (t > 1e-3) & np.isfinite(t)
                if normal[2] == 0.0:  # walls stop at 12 m height
                    z = origins[:, 2] + t * dirs[:, 2]
                    ok &= z < 12.0
                best = np.where(ok & (t < best), t, best)
            for lo, hi in zip(self.boxes_lo, self.boxes_hi):
                t1 = (lo[None, :] - origins) / dirs
                t2 = (hi[None, :] - origins) / dirs
                tmin = np.nanmax(np.minimum(t1, t2), axis=1)
                tmax = np.nanmin(np.maximum(t1, t2), axis=1)
                ok = (tmax >= tmin) & (tmin > 1e-3)
                best = np.where(ok & (tmin < best), tmin, best)
            for cx, cy, r, h in self.poles:
                ox, oy = origins[:, 0] - cx, origins[:, 1] - cy
                a = dirs[:, 0] ** 2 + dirs[:, 1] ** 2
                b = 2 * (ox * dirs[:, 0] + oy * dirs[:, 1])
                c = ox ** 2 + oy ** 2 - r * r
                disc = b * b - 4 * a * c
                t = (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a)
                z = origins[:, 2] + t * dirs[:, 2]
                ok = (disc > 0) & (t > 1e-3) & (z < h) & (z > 0)
                best = np.where(ok & (t < best), t, best)
        best[best > max_range] = np.inf
        return best


class Drive:
    """Sensor pose over time: forward at `speed` m/s along x, weaving gently in y, heading along the motion."""

    def __init__(self, speed=5.0, sway=0.6, sway_rate=0.5, height=1.8, start_x=0.0):
        self.speed, self.sway, self.sway_rate, self.height, self.start_x = speed, sway, sway_rate, height, start_x

    def position(self, t):
        t = np.asarray(t, dtype=float)
        return np.stack([self.start_x + self.speed * t, self.sway * np.sin(self.sway_rate * t),
                         np.full_like(t, self.height)], axis=-1)

    def heading(self, t):
        t = np.asarray(t, dtype=float)
        return np.arctan2(self.sway * self.sway_rate * np.cos(self.sway_rate * t), self.speed)

    def matrix(self, t):
        m = np.eye(4)
        m[:3, :3] = rot_z(float(self.heading(t)))
        m[:3, 3] = self.position(t)
        return m


def simulate_sweep(street, drive, k, moving=True, azimuth_steps=1800, noise=0.01, seed=None):
    """Sweep k (start time k * SCAN_PERIOD) as a POINT_DTYPE array in the sensor frame, firing order within
    each ring, ring 0 lowest; time = seconds since the sweep start. `moving`: every ray is cast from the pose
    at its firing time (motion distortion, as a real spinning lidar); else from the pose at the sweep end."""
    start = k * SCAN_PERIOD
    steps = np.arange(azimuth_steps)
    frac = steps / float(azimuth_steps)
    azimuth = 2 * math.pi * frac  # counter-clockwise from +x
    elev = np.radians(VLP16_ELEVATIONS_DEG)
    az, el = np.meshgrid(azimuth, elev)  # rings x steps
    ring = np.repeat(np.arange(len(elev)), azimuth_steps).astype(np.uint16)
    az, el = az.reshape(-1), el.reshape(-1)
    point_time = np.tile(frac * SCAN_PERIOD, len(elev))
    local = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)
    when = start + (point_time if moving else np.full_like(point_time, SCAN_PERIOD))
    heading = drive.heading(when)
    c, s = np.cos(heading), np.sin(heading)
    world = np.stack([c * local[:, 0] - s * local[:, 1], s * local[:, 0] + c * local[:, 1], local[:, 2]], axis=1)
    origins = drive.position(when)
    ranges = street.cast(origins, world)
    rng = np.random.RandomState(k if seed is None else seed)
    ranges = ranges + rng.normal(0.0, noise, ranges.shape)
    hit = np.isfinite(ranges) & (ranges > 0.5)
    pts = np.zeros(int(hit.sum()), dtype=POINT_DTYPE)
    xyz = local[hit] * ranges[hit, None]
    pts["x"], pts["y"], pts["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    pts["intensity"] = (20.0 + 3.0 * ring[hit] + 50.0 * (np.abs(xyz[:, 2] + drive.height) < 0.05)).astype(np.float32)
    pts["time"] = point_time[hit]
    pts["ring"] = ring[hit]
    # Velodyne order: by azimuth (firing), rings interleaved
    order = np.lexsort((pts["ring"], pts["time"]))
    return pts[order]


def sweep_end_poses(drive, count):
    """World <- sensor at the end of sweeps 0..count-1."""
    return [drive.matrix((k + 1) * SCAN_PERIOD) for k in range(count)]


# --------------------------------------------------------------------------------------------------------
# LOAM features in numpy (for feeding the odometry and mapping nodelets without scan registration)


def extract_features(points, half_window=5, sectors=6, threshold=0.1, max_sharp=2, max_less_sharp=20,
                     max_flat=4, leaf=0.2):
    """LOAM's feature classes of one sweep (POINT_DTYPE arrays, ring-ordered): sharp, less_sharp, flat,
    less_flat, full. Curvature over +-half_window neighbours along the ring, features picked evenly per
    sector with neighbour suppression, as scan registration does."""
    out = {k: [] for k in ("sharp", "less_sharp", "flat", "less_flat", "full")}
    for r in np.unique(points["ring"]):
        ring = points[points["ring"] == r]
        ring = ring[np.argsort(ring["time"], kind="stable")]
        out["full"].append(ring)
        n = ring.shape[0]
        if n < 2 * half_window + 2 * sectors:
            continue
        xyz = np.stack([ring["x"], ring["y"], ring["z"]], axis=1).astype(np.float64)
        kernel = np.ones(2 * half_window + 1)
        kernel[half_window] = -2 * half_window
        diff = np.stack([np.convolve(xyz[:, i], kernel[::-1], mode="same") for i in range(3)], axis=1)
        curv = np.sum(diff * diff, axis=1)
        valid = np.zeros(n, dtype=bool)
        valid[half_window:n - half_window] = True
        # occlusion / depth jump: drop candidates next to a large gap (far side)
        rng_ = np.linalg.norm(xyz, axis=1)
        gap = np.sum(np.diff(xyz, axis=0) ** 2, axis=1)
        jump = np.where(gap > 0.1)[0]
        for j in jump:
            far = j if rng_[j] > rng_[j + 1] else j + 1
            lo, hi = (far - half_window, far + 1) if far == j else (far, far + half_window + 1)
            valid[max(lo, 0):min(hi, n)] = False
        picked = ~valid
        label = np.zeros(n, dtype=np.int8)
        first, last = half_window, n - half_window
        bounds = [first + (last - first) * s // sectors for s in range(sectors + 1)]

        def suppress(i):
            picked[i] = True
            for step in (1, -1):
                for m in range(1, half_window + 1):
                    a, b = i + step * m, i + step * (m - 1)
                    if a < 0 or a >= n or np.sum((xyz[a] - xyz[b]) ** 2) > 0.05:
                        break
                    picked[a] = True

        for s in range(sectors):
            sb, se = bounds[s], bounds[s + 1]
            if se <= sb:
                continue
            idx = np.arange(sb, se)
            order = idx[np.argsort(curv[idx])]
            count = 0
            for i in order[::-1]:
                if curv[i] <= threshold:
                    break
                if picked[i]:
                    continue
                count += 1
                if count <= max_sharp:
                    label[i] = 2
                elif count <= max_less_sharp:
                    label[i] = 1
                else:
                    break
                suppress(i)
            count = 0
            for i in order:
                if curv[i] >= threshold:
                    break
                if picked[i]:
                    continue
                label[i] = -1
                count += 1
                suppress(i)
                if count >= max_flat:
                    break
        out["sharp"].append(ring[label == 2])
        out["less_sharp"].append(ring[label > 0])
        out["flat"].append(ring[label == -1])
        less_flat = ring[(label <= 0) & valid]
        if leaf > 0 and less_flat.shape[0]:
            keys = np.floor(np.stack([less_flat["x"], less_flat["y"], less_flat["z"]], axis=1) / leaf).astype(np.int64)
            _, keep = np.unique(keys, axis=0, return_index=True)
            less_flat = less_flat[np.sort(keep)]
        out["less_flat"].append(less_flat)
    return {k: (np.concatenate(v) if v else np.zeros(0, dtype=POINT_DTYPE)) for k, v in out.items()}


def deskew_to_end(points, motion):
    """Moves every point (sensor frame at its firing time) into the sensor frame at the sweep end, given
    motion = sweep start <- sweep end at constant velocity (rotation about z only, small)."""
    s = points["time"].astype(np.float64) / SCAN_PERIOD
    yaw = math.atan2(motion[1, 0], motion[0, 0])
    xyz = np.stack([points["x"], points["y"], points["z"]], axis=1).astype(np.float64)
    # start <- t: yaw s*yaw, translation s*t; end <- start: inverse(motion)
    c, sn = np.cos(s * yaw), np.sin(s * yaw)
    at_start = np.stack([c * xyz[:, 0] - sn * xyz[:, 1], sn * xyz[:, 0] + c * xyz[:, 1], xyz[:, 2]], axis=1)
    at_start += s[:, None] * motion[:3, 3][None, :]
    inv = np.linalg.inv(motion)
    at_end = at_start @ inv[:3, :3].T + inv[:3, 3]
    out = points.copy()
    out["x"], out["y"], out["z"] = at_end[:, 0], at_end[:, 1], at_end[:, 2]
    out["time"] = SCAN_PERIOD
    return out


# --------------------------------------------------------------------------------------------------------
# Frame-by-frame replay into a running pipeline


def read_bag_clouds(path, topic="velodyne_points"):
    import rosbag
    with rosbag.Bag(path) as bag:
        return [msg for _, msg, _ in bag.read_messages(topics=[topic])]


def make_test_bag(directory, sweeps=40, sensor="VLP16"):
    """Runs make_test_bag; returns (bag path, ground truth path)."""
    bag, gt = os.path.join(directory, "street.bag"), os.path.join(directory, "street_gt.txt")
    subprocess.run([devel_tool("make_test_bag"), bag, gt, sensor, str(sweeps)], check=True,
                   stdout=subprocess.PIPE, timeout=120)
    return bag, gt


class Replayer:
    """Publishes PointCloud2 sweeps on NS/velodyne_points one at a time and waits for each answer on
    NS/aft_mapped_to_init (matched by stamp)."""

    def __init__(self, ns="", timeout=10.0):
        prefix = ("/" + ns.strip("/")) if ns.strip("/") else ""
        self.ns = prefix
        self.timeout = timeout
        self.answers = StampCollector(prefix + "/aft_mapped_to_init", Odometry)
        self.pub = rospy.Publisher(prefix + "/velodyne_points", PointCloud2, queue_size=1)
        self.latencies = []

    def wait_ready(self, timeout=40.0):
        """Waits for the whole pipeline to be wired; returns the topics still missing an end."""
        missing = wait_for_graph(subscribed=[self.ns + t for t in ("/velodyne_points", "/laser_features",
                                                                    "/laser_odom_frame")],
                                 published=[self.ns + "/aft_mapped_to_init"], timeout=timeout)
        if not wait_connected(self.pub, timeout=10.0):
            missing.append(self.ns + "/velodyne_points (connection)")
        if not wait_connected(self.answers.sub, timeout=10.0):
            missing.append(self.ns + "/aft_mapped_to_init (connection)")
        return missing

    def publish(self, msg):
        self.pub.publish(msg)
        return msg.header.stamp.to_nsec()

    def wait(self, stamp_ns, t0=None):
        answer = self.answers.wait_for(stamp_ns, self.timeout)
        if answer is not None and t0 is not None:
            self.latencies.append(time.time() - t0)
        return answer

    def play(self, clouds, before_frame=None, log_every=10):
        """Plays `clouds` (PointCloud2) frame by frame; returns the answer of each (None: unanswered)."""
        answers = []
        for i, msg in enumerate(clouds):
            if before_frame is not None:
                before_frame(i, answers)
            t0 = time.time()
            stamp = self.publish(msg)
            answer = self.wait(stamp, t0)
            answers.append(answer)
            if answer is None:
                print("%s frame %d (stamp %.3f): no answer within %.1f s" % (self.ns or "/", i, stamp * 1e-9,
                                                                             self.timeout), flush=True)
            elif log_every and i % log_every == 0:
                print("%s frame %d/%d answered" % (self.ns or "/", i + 1, len(clouds)), flush=True)
        return answers


def answered_matrices(answers):
    """4x4 poses of the answers, the previous one (or identity) standing in for a missing answer."""
    out = []
    for a in answers:
        out.append(pose_to_matrix(a.pose.pose) if a is not None else (out[-1] if out else np.eye(4)))
    return out


# --------------------------------------------------------------------------------------------------------
# Simulated sequences (aloam_sim) played into a running pipeline


def simulate(directory, name, sensor, scene, trajectory, duration, seed, keep_every=1):
    """Runs aloam_sim into DIRECTORY/NAME.bag; returns the bag path. Seeded, so every run is the same.
    keep_every > 1 publishes only every N-th sweep (a throttled topic, stamps N sweep periods apart)."""
    return _run_sim(directory, name, ["--sensor", sensor, "--scene", scene, "--trajectory", trajectory,
                                      "--duration", str(duration), "--seed", str(seed),
                                      "--keep-every", str(int(keep_every))])


def simulate_family(directory, name, sensor, family, seed, duration):
    """As simulate, with the scene and motion drawn from FAMILY by SEED (aloam_sim --family); returns
    (bag path, aloam_sim's `draw:` line with every drawn value)."""
    bag, output = _run_sim(directory, name, ["--sensor", sensor, "--family", family, "--seed", str(seed),
                                             "--duration", str(duration)], with_output=True)
    draw = next((line[len("draw: "):] for line in output.splitlines() if line.startswith("draw: ")), "")
    return bag, draw


def _run_sim(directory, name, args, with_output=False):
    bag = os.path.join(directory, name + ".bag")
    proc = subprocess.run([devel_tool("aloam_sim")] + args + ["--bag", bag],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True, timeout=300)
    if proc.returncode != 0:
        raise AssertionError("aloam_sim failed (%d):\n%s" % (proc.returncode, proc.stdout))
    print(proc.stdout.strip().splitlines()[-4], flush=True)
    return (bag, proc.stdout) if with_output else bag


def bag_ground_truth(path, topic="ground_truth"):
    """World <- sensor matrices of the bag's nav_msgs/Odometry ground truth, in recording order."""
    import rosbag
    with rosbag.Bag(path) as bag:
        return [pose_to_matrix(msg.pose.pose) for _, msg, _ in bag.read_messages(topics=[topic])]


MIN_STEP_M = 0.05  # true steps shorter than this are not checked for direction


def backward_steps(estimate, truth):
    """(estimated steps against the true step, true steps longer than MIN_STEP_M), relative to the first pose."""
    est, gt = relative_to_first(estimate), relative_to_first(truth)
    backward = steps = 0
    for i in range(len(gt) - 1):
        true_step = gt[i + 1][:3, 3] - gt[i][:3, 3]
        if np.linalg.norm(true_step) <= MIN_STEP_M:
            continue
        steps += 1
        if float(np.dot(true_step, est[i + 1][:3, 3] - est[i][:3, 3])) < 0.0:
            backward += 1
    return backward, steps


def relative_to_first(matrices):
    first_inv = np.linalg.inv(matrices[0])
    return [first_inv @ m for m in matrices]


def position_errors(estimate, truth):
    """Per-frame position error (m) and heading error (deg) of two trajectories, both relative to their
    first pose (no alignment: what a user sees against the truth)."""
    est, gt = relative_to_first(estimate), relative_to_first(truth)
    positions = np.array([np.linalg.norm(e[:3, 3] - g[:3, 3]) for e, g in zip(est, gt)])
    angles = []
    for e, g in zip(est, gt):
        r = g[:3, :3].T @ e[:3, :3]
        angles.append(math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(r) - 1.0) / 2.0)))))
    return positions, np.array(angles)


def path_length(matrices):
    return float(sum(np.linalg.norm(b[:3, 3] - a[:3, 3]) for a, b in zip(matrices, matrices[1:])))


class DiagnosticsWatcher:
    """Keeps the newest /diagnostics status of each name as {key: value}, with its level and message."""

    def __init__(self, history_keys=()):
        self._lock = threading.Lock()
        self.latest = {}
        self.history_keys = tuple(history_keys)
        self.history = {}  # (status name, key) -> every value seen, in arrival order (history_keys only)
        self.sub = rospy.Subscriber("/diagnostics", DiagnosticArray, self._cb, queue_size=100)

    def _cb(self, msg):
        with self._lock:
            for st in msg.status:
                values = {kv.key: kv.value for kv in st.values}
                self.latest[st.name] = (st.level, st.message, values)
                for key in self.history_keys:
                    if key in values:
                        self.history.setdefault((st.name, key), []).append(values[key])

    def values_seen(self, fragment, key):
        """Every value of KEY seen in the statuses whose name ends with FRAGMENT (history_keys only)."""
        with self._lock:
            return [v for (name, k), seen in self.history.items() if name.endswith(fragment) and k == key
                    for v in seen]

    def find(self, fragment):
        """(level, message, values) of the newest status whose name ends with FRAGMENT, else None."""
        with self._lock:
            for name, status in self.latest.items():
                if name.endswith(fragment):
                    return status
        return None

    def wait_frames(self, fragment, frames, timeout=15.0):
        """Waits for a status of FRAGMENT reporting at least FRAMES processed frames; returns it or None."""
        deadline = time.time() + timeout
        while time.time() < deadline and not rospy.is_shutdown():
            status = self.find(fragment)
            if status is not None and int(status[2].get("frames", "0")) >= frames:
                return status
            time.sleep(0.1)
        return None


def play_simulated(test, bag, ns="", timeout=20.0):
    """Plays the clouds of BAG into the pipeline at NS frame by frame (each waits for its answer, so no
    frame is skipped however slow the machine), asserting every answer is finite; returns
    (answers, ground truth matrices, wall seconds)."""
    clouds = read_bag_clouds(bag)
    truth = bag_ground_truth(bag)
    test.assertEqual(len(clouds), len(truth))
    replayer = Replayer(ns=ns, timeout=timeout)
    test.assertEqual(replayer.wait_ready(), [], "pipeline %s not wired" % (ns or "/"))
    t0 = time.time()
    answers = replayer.play(clouds, log_every=20)
    elapsed = time.time() - t0
    test.assertEqual([i for i, a in enumerate(answers) if a is None], [], "sweeps without aft_mapped_to_init")
    test.assertEqual([i for i, a in enumerate(answers) if not pose_is_finite(a)], [], "non-finite poses")
    replayer.answers.unregister()
    return answers, truth, elapsed


def evaluate(test, name, answers, truth, segments):
    """aloam_eval of the answered poses against the truth (both written relative to their first pose, as
    NAME.txt and NAME_gt.txt in the scratch directory)."""
    trajectory, gt = test.path(name + ".txt"), test.path(name + "_gt.txt")
    write_kitti(trajectory, answered_matrices(answers))
    write_kitti(gt, truth)
    metrics, report = run_eval(gt, trajectory, segments=segments)
    return metrics, report
