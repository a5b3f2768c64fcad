#!/usr/bin/env python3
"""The whole pipeline through aloam.launch (pipeline_playback.test).

1. sensor:=VLP16 (root namespace): a 40-sweep bag written by make_test_bag (simulated VLP-16 drive with
   motion distortion and exact ground truth) replayed sweep by sweep, each waiting for its
   aft_mapped_to_init: every sweep answered with its stamp (camera_init -> aft_mapped), then aloam_eval
   against the ground truth over 5, 10, 20 m segments: translation drift and ATE under bounds; each
   nodelet reports on /diagnostics.
2. sensor:=HDL64 (namespace kitti): when ../shared/data/kitti00_101 exists, test/tools/replay_kitti.py
   over its 101 frames: every frame answered, and aloam_eval from frame 6 over 10..70 m segments with
   calib.txt within A-LOAM's figures on these frames (drift 1.449 %, ATE 0.167 m). Skipped with a printed
   reason when the data is absent.
"""
import os
import subprocess
import sys
import time

import numpy as np
import rospy
from diagnostic_msgs.msg import DiagnosticArray
import rostest

import aloam_rostest_utils as u

# Bag check: aloam_offline on the same bag measures drift 0.487 %, ATE 0.029 m; the nodelet pipeline
# (this test) measured the values printed by test_1. Bounds with margin:
MAX_BAG_DRIFT_PERCENT = 1.0
MAX_BAG_ATE_M = 0.06
# KITTI 00 frames 0-100 from frame 6, segments 10..70 m: A-LOAM's figures (README).
MAX_KITTI_DRIFT_PERCENT = 1.449
MAX_KITTI_ATE_M = 0.167
KITTI_FRAMES = 101
NODELETS = ("scan_registration", "laser_odometry", "laser_mapping")


class TestPipelinePlayback(u.ScratchTestCase):

    def test_1_simulated_bag(self):
        bag, gt = u.make_test_bag(self.scratch, sweeps=40, sensor="VLP16")
        clouds = u.read_bag_clouds(bag)
        self.assertEqual(len(clouds), 40)
        diagnostics = []
        diag_sub = rospy.Subscriber("/diagnostics", DiagnosticArray, lambda m: diagnostics.extend(m.status))
        replayer = u.Replayer(ns="", timeout=10.0)
        missing = replayer.wait_ready()
        self.assertEqual(missing, [], "pipeline not wired")
        t0 = time.time()
        answers = replayer.play(clouds)
        elapsed = time.time() - t0
        unanswered = [i for i, a in enumerate(answers) if a is None]
        self.assertEqual(unanswered, [], "sweeps without aft_mapped_to_init")
        for cloud, answer in zip(clouds, answers):
            self.assertEqual(answer.header.stamp, cloud.header.stamp)
            self.assertEqual(answer.header.frame_id, "camera_init")
            self.assertEqual(answer.child_frame_id, "aft_mapped")
            self.assertTrue(u.pose_is_finite(answer))
        trajectory = self.path("trajectory.txt")
        u.write_kitti(trajectory, u.answered_matrices(answers))
        metrics, report = u.run_eval(gt, trajectory, segments="5,10,20")
        print(report, flush=True)
        drift, ate = metrics["translation_drift_percent"], metrics["ate_rmse_m"]
        print("simulated bag: 40/40 answered in %.1f s (latency mean %.0f ms, max %.0f ms); drift %.3f %% "
              "(<= %.1f), ATE %.3f m (<= %.2f)" % (elapsed, 1000 * np.mean(replayer.latencies),
                                                  1000 * max(replayer.latencies), drift, MAX_BAG_DRIFT_PERCENT,
                                                  ate, MAX_BAG_ATE_M), flush=True)
        self.assertLessEqual(drift, MAX_BAG_DRIFT_PERCENT)
        self.assertLessEqual(ate, MAX_BAG_ATE_M)
        # each nodelet reports on /diagnostics (README)
        deadline = time.time() + 5.0
        names = set()
        while time.time() < deadline:
            names = {st.name for st in list(diagnostics)}
            if all(any(n in name and "kitti" not in name for name in names) for n in NODELETS):
                break
            time.sleep(0.2)
        diag_sub.unregister()
        print("diagnostics: %s" % sorted(names), flush=True)
        for n in NODELETS:
            self.assertTrue(any(n in name and "kitti" not in name for name in names), "no diagnostics from %s" % n)

    def test_2_kitti(self):
        data = u.kitti_dir()
        if data is None:
            reason = ("SKIPPED: no KITTI data: none of %s holds velodyne/*.bin and poses_kitti_gt.txt"
                      % ", ".join(u.kitti_candidates()))
            print(reason, flush=True)
            self.skipTest(reason)
        frames = len([f for f in os.listdir(os.path.join(data, "velodyne")) if f.endswith(".bin")])
        self.assertEqual(frames, KITTI_FRAMES, "%s holds %d frames" % (data, frames))
        missing = u.wait_for_graph(subscribed=["/kitti/velodyne_points", "/kitti/laser_features",
                                               "/kitti/laser_odom_frame"],
                                   published=["/kitti/aft_mapped_to_init"], timeout=40)
        self.assertEqual(missing, [], "KITTI pipeline not wired")
        trajectory = self.path("kitti.txt")
        replay = os.path.join(u.package_dir(), "test", "tools", "replay_kitti.py")
        t0 = time.time()
        proc = subprocess.run([sys.executable, replay, data, trajectory, "--timeout", "20", "__ns:=/kitti",
                               "__name:=replay_kitti"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              universal_newlines=True, timeout=240)
        elapsed = time.time() - t0
        print(proc.stdout[-2000:], flush=True)
        self.assertEqual(proc.returncode, 0, "replay_kitti.py failed (unanswered frames?)")
        self.assertIn("%d frames, %d answered, 0 unanswered" % (KITTI_FRAMES, KITTI_FRAMES), proc.stdout)
        self.assertEqual(len(u.read_kitti(trajectory)), KITTI_FRAMES)
        metrics, report = u.run_eval(os.path.join(data, "poses_kitti_gt.txt"), trajectory,
                                     segments="10,20,30,40,50,60,70",
                                     extra=["--calib", os.path.join(data, "calib.txt"), "--start", "6"])
        print(report, flush=True)
        drift, ate = metrics["translation_drift_percent"], metrics["ate_rmse_m"]
        print("KITTI 00 0-100: %d/%d answered in %.1f s; from frame 6: drift %.3f %% (<= %.3f), ATE %.3f m "
              "(<= %.3f)" % (KITTI_FRAMES, KITTI_FRAMES, elapsed, drift, MAX_KITTI_DRIFT_PERCENT, ate,
                             MAX_KITTI_ATE_M), flush=True)
        self.assertLessEqual(drift, MAX_KITTI_DRIFT_PERCENT)
        self.assertLessEqual(ate, MAX_KITTI_ATE_M)


if __name__ == "__main__":
    rospy.init_node("test_pipeline_playback")
    rostest.rosrun("aloam_nodelet", "pipeline_playback", TestPipelinePlayback)
