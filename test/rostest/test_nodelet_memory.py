#!/usr/bin/env python3
"""Memory of the nodelet manager over a longer drive (nodelet_memory.test).

long_drive_publisher feeds SWEEPS sweeps of the endless simulated street (sim::LongDrive, 10 m/s) into the
pipeline, each after the previous one was answered. Meanwhile this node samples the manager's resident
memory (/proc) and the mapping's diagnostics. With cubes of 25 m evicted beyond 150 m the map stops growing
after a few hundred sweeps; then the manager's memory must flatten too: no queue, path or cache grows with
the drive. Asserts: every sweep answered, cubes evicted, the map in the second half at most 1.5 times as
large as in the first, RSS growth over the second half within MAX_LATE_GROWTH_MB, and the trajectory kept
for save_trajectory cut to trajectory_max_poses. (The 18,000-sweep run of the core
is test/longrun/run_long_drive.sh in test.sh.)
"""
import subprocess
import threading
import time
import xmlrpc.client

import rosgraph
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray

import aloam_rostest_utils as u
from aloam_nodelet.srv import SaveTrajectory

SWEEPS = 3000
MAX_LATE_GROWTH_MB = 20.0
TRAJECTORY_MAX_POSES = 500  # as set in nodelet_memory.test


def resident_mb(pid):
    with open("/proc/%d/status" % pid) as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return 0.0


class TestNodeletMemory(u.ScratchTestCase):

    def test_memory_flattens(self):
        uri = rosgraph.Master("/test_nodelet_memory").lookupNode("/aloam_manager")
        code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/test_nodelet_memory")
        self.assertEqual(code, 1)
        mapping = {}
        lock = threading.Lock()

        def diagnostics_cb(msg):
            for status in msg.status:
                if "laser_mapping" in status.name:
                    with lock:
                        mapping.update({kv.key: kv.value for kv in status.values})

        sub = rospy.Subscriber("/diagnostics", DiagnosticArray, diagnostics_cb, queue_size=20)
        self.assertEqual(u.wait_for_graph(subscribed=["/velodyne_points", "/laser_features", "/laser_odom_frame"],
                                          published=["/aft_mapped_to_init_high_frec"], timeout=40), [])
        log = open(self.path("publisher.txt"), "w")
        proc = subprocess.Popen([u.devel_tool("long_drive_publisher"), str(SWEEPS)], stdout=log,
                                stderr=subprocess.STDOUT)
        samples = []  # (wall s, RSS MB, map cubes, map points, cubes evicted)
        t0 = time.time()
        while proc.poll() is None and time.time() - t0 < 360:
            time.sleep(2.0)
            with lock:
                cubes = int(mapping.get("map cubes", 0))
                points = int(mapping.get("map edge points", 0)) + int(mapping.get("map plane points", 0))
                evicted = int(mapping.get("cubes evicted", 0))
            samples.append((time.time() - t0, resident_mb(pid), cubes, points, evicted))
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        log.close()
        sub.unregister()
        with open(self.path("publisher.txt")) as f:
            output = f.read()
        print(output[-300:], flush=True)
        print("%8s %8s %7s %10s %8s" % ("wall s", "RSS MB", "cubes", "points", "evicted"), flush=True)
        for s in samples[::max(1, len(samples) // 15)] + samples[-1:]:
            print("%8.0f %8.1f %7d %10d %8d" % s, flush=True)
        self.assertEqual(proc.returncode, 0, "long_drive_publisher: sweeps unanswered")
        self.assertGreaterEqual(len(samples), 4)
        half = len(samples) // 2
        first, second = samples[:half], samples[half:]
        growth = second[-1][1] - second[0][1]
        print("manager RSS %.1f MB at the middle, %.1f MB at the end: %+.1f MB (<= %.1f); map at most %d cubes in "
              "the first half, %d in the second; %d cubes evicted"
              % (second[0][1], second[-1][1], growth, MAX_LATE_GROWTH_MB, max(s[2] for s in first),
                 max(s[2] for s in second), samples[-1][4]), flush=True)
        self.assertGreater(samples[-1][4], 0, "no cube evicted")
        self.assertLessEqual(max(s[3] for s in second), 1.5 * max(s[3] for s in first), "the map kept growing")
        self.assertLessEqual(growth, MAX_LATE_GROWTH_MB, "the manager's memory kept growing")
        # The trajectory kept for save_trajectory is bounded too (trajectory_max_poses in the .test).
        path = self.path("trajectory.tum")
        response = rospy.ServiceProxy("/laser_mapping/save_trajectory", SaveTrajectory)(path, "tum")
        self.assertTrue(response.success, response.message)
        with open(path) as f:
            kept = sum(1 for line in f if line.strip() and not line.startswith("#"))
        print("save_trajectory: %d poses kept (trajectory_max_poses %d)" % (kept, TRAJECTORY_MAX_POSES), flush=True)
        self.assertGreaterEqual(kept, TRAJECTORY_MAX_POSES)
        self.assertLessEqual(kept, TRAJECTORY_MAX_POSES * 1.1)


if __name__ == "__main__":
    rospy.init_node("test_nodelet_memory")
    rostest.rosrun("aloam_nodelet", "nodelet_memory", TestNodeletMemory)
