#!/usr/bin/env python3
"""LaserMapping alone in a nodelet manager (nodelet_mapping.test), fed aloam_nodelet/OdometryFrame messages
built here: synthetic VLP-16 sweeps (sensor at rest during each sweep, so the clouds are already in the
sensor frame at the sweep end), LOAM features from aloam_rostest_utils.extract_features, and odometry
poses = the simulated drive with a drift added (2.5 cm/sweep short in x, 2 cm/sweep climb, 0.05 deg/sweep
of yaw), as scan-to-scan odometry drifts.

- aft_mapped_to_init and aft_mapped_to_init_high_frec for every input, with its stamp, camera_init ->
  aft_mapped, finite; mapping removes the injected drift (poses close to the drive)
- TF camera_init -> aft_mapped at each answered stamp, equal to aft_mapped_to_init
- aft_mapped_path, velodyne_cloud_registered, laser_cloud_surround, laser_cloud_map when subscribed,
  well-formed
- ~save_map writes a PCD (binary, x y z ...) with the map's points; an unwritable path fails cleanly
- ~save_trajectory writes N KITTI rows (first identity, matching the answers) or N TUM rows with the
  input stamps; an unknown format fails cleanly
- ~reset: the next frame starts a new map (trajectory of one pose, a map of one frame, no correction);
  the high-rate answer of that frame must not use the reset map's correction either (test_5)
- the high-rate answer of every frame is within 0.1 m of the mapped answer of the same frame
- ~save_map to an unwritable path answers success=false with a message (test_6)
"""
import math
import os
import time

import numpy as np
import rospy
import rostest
import tf2_ros
from nav_msgs.msg import Odometry, Path
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import Trigger

from aloam_nodelet.msg import OdometryFrame
from aloam_nodelet.srv import SaveMap, SaveTrajectory

import aloam_rostest_utils as u

FRAMES = 30
DRIFT_X, DRIFT_Z, DRIFT_YAW_DEG = -0.025, 0.02, 0.05  # per sweep
# Measured: final mapped error 0.095 m horizontal, 0.194 m vertical, 0.04 deg yaw, against an injected
# odometry error of 0.81 m horizontal / 0.58 m vertical (1.0 m). Fed the exact drive instead, mapping ends
# at 0.09 m / 0.18 m: the vertical part is the known climb of a sparse 16-beam map (core/laser_mapping.h),
# not the injected drift.
MAX_HORIZONTAL_ERROR_M = 0.2
MAX_VERTICAL_ERROR_M = 0.35
MAX_MAPPED_YAW_ERROR_DEG = 0.5
MAX_HIGH_RATE_GAP_M = 0.1


def drifted(truth_rel):
    out = []
    for k, m in enumerate(truth_rel):
        d = np.eye(4)
        d[:3, :3] = u.rot_z(math.radians(DRIFT_YAW_DEG * k))
        d[:3, 3] = [DRIFT_X * k, 0.0, DRIFT_Z * k]
        out.append(d @ m)
    return out


def frame_message(features, odom, prev_odom, stamp, first):
    msg = OdometryFrame()
    msg.header.stamp = stamp
    msg.header.frame_id = "camera_init"
    msg.child_frame_id = "laser_odom"
    msg.sensor_frame_id = "velodyne"
    u.matrix_to_pose(odom, msg.pose)
    u.matrix_to_pose(np.linalg.inv(prev_odom) @ odom, msg.motion)
    msg.status = OdometryFrame.STATUS_INITIALIZED if first else OdometryFrame.STATUS_OK
    msg.distorted = False
    msg.corner_matches, msg.plane_matches, msg.constraint = (0, 0, 0.0) if first else (150, 350, 70.0)
    msg.corners = u.cloud_message(features["less_sharp"], stamp)
    msg.surfs = u.cloud_message(features["less_flat"], stamp)
    msg.full = u.cloud_message(features["full"], stamp)
    return msg


class TestLaserMappingNodelet(u.ScratchTestCase):

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        street, drive = u.Street(), u.Drive(speed=5.0)
        truth = u.sweep_end_poses(drive, FRAMES)
        cls.truth = [np.linalg.inv(truth[0]) @ m for m in truth]
        cls.odom = drifted(cls.truth)
        cls.features = [u.extract_features(u.simulate_sweep(street, drive, k, moving=False)) for k in range(FRAMES)]
        cls.base = rospy.Time(5000)
        cls.stamps = [cls.base + rospy.Duration(0.1 * k) for k in range(FRAMES)]
        cls.pub = rospy.Publisher("/laser_odom_frame", OdometryFrame, queue_size=5)
        missing = u.wait_for_graph(subscribed=["/laser_odom_frame"], published=["/aft_mapped_to_init"], timeout=40)
        assert not missing, "laser mapping not up: %s" % missing
        cls.mapped = u.StampCollector("/aft_mapped_to_init", Odometry)
        cls.high = u.StampCollector("/aft_mapped_to_init_high_frec", Odometry)
        cls.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(1000))
        cls.tf_listener = tf2_ros.TransformListener(cls.tf_buffer)
        for endpoint in (cls.pub, cls.mapped.sub, cls.high.sub):
            assert u.wait_connected(endpoint), "no connection to the mapping nodelet"

    def feed(self, indices, stamps, odom, min_period=0.1):
        """Feeds frames at most at 10 Hz, never ahead of the previous answer; returns the answers."""
        answers = []
        prev = None
        for i, stamp in zip(indices, stamps):
            t0 = time.time()
            msg = frame_message(self.features[i], odom[i], odom[prev] if prev is not None else odom[i], stamp,
                                first=prev is None)
            self.pub.publish(msg)
            answers.append(self.mapped.wait_for(stamp.to_nsec(), 10.0))
            prev = i
            time.sleep(max(0.0, min_period - (time.time() - t0)))
        return answers

    def service(self, name, srv_type):
        full = "/laser_mapping/" + name
        self.assertTrue(u.wait_for_service(full, 10), "%s not advertised" % full)
        return rospy.ServiceProxy(full, srv_type)

    def test_1_mapping_answers_every_frame(self):
        extras = {"/aft_mapped_path": Path, "/velodyne_cloud_registered": PointCloud2,
                  "/laser_cloud_surround": PointCloud2, "/laser_cloud_map": PointCloud2}
        extra = u.connected_collectors(self, extras)
        answers = self.feed(range(FRAMES), self.stamps, self.odom)
        missing = [i for i, a in enumerate(answers) if a is None]
        self.assertEqual(missing, [], "frames without aft_mapped_to_init")
        for i, stamp in enumerate(self.stamps):
            high = self.high.wait_for(stamp.to_nsec(), 10.0)
            self.assertIsNotNone(high, "no aft_mapped_to_init_high_frec for frame %d" % i)
            for msg in (answers[i], high):
                self.assertEqual(msg.header.stamp, stamp)
                self.assertEqual(msg.header.frame_id, "camera_init")
                self.assertEqual(msg.child_frame_id, "aft_mapped")
                self.assertTrue(u.pose_is_finite(msg))
        self.assertEqual(len(self.mapped.stamps()), FRAMES, "exactly one aft_mapped_to_init per frame")
        # The high-rate answer is the odometry pose corrected with the previous frame's correction: it
        # differs from the mapped pose of the same frame by this frame's refinement only.
        gaps = [np.linalg.norm(u.pose_to_matrix(answers[i].pose.pose)[:3, 3]
                               - u.pose_to_matrix(self.high.by_stamp[s.to_nsec()].pose.pose)[:3, 3])
                for i, s in enumerate(self.stamps)]
        print("high-rate vs mapped answer of the same frame: max %.3f m" % max(gaps), flush=True)
        self.assertLess(max(gaps), MAX_HIGH_RATE_GAP_M)
        self.assertEqual(len(self.high.stamps()), FRAMES, "exactly one high-rate answer per frame")

        mapped = [u.pose_to_matrix(a.pose.pose) for a in answers]
        horizontal = [np.linalg.norm(m[:2, 3] - t[:2, 3]) for m, t in zip(mapped, self.truth)]
        vertical = [abs(m[2, 3] - t[2, 3]) for m, t in zip(mapped, self.truth)]
        errors = [np.linalg.norm(m[:3, 3] - t[:3, 3]) for m, t in zip(mapped, self.truth)]
        odom_errors = [np.linalg.norm(o[:3, 3] - t[:3, 3]) for o, t in zip(self.odom, self.truth)]
        yaw = math.degrees(abs(math.atan2(mapped[-1][1, 0], mapped[-1][0, 0])
                               - math.atan2(self.truth[-1][1, 0], self.truth[-1][0, 0])))
        print("mapping: max error %.3f m horizontal, %.3f m vertical; final %.3f m, yaw %.2f deg "
              "(odometry input: final %.3f m)" % (max(horizontal), max(vertical), errors[-1], yaw, odom_errors[-1]),
              flush=True)
        self.assertLess(max(horizontal), MAX_HORIZONTAL_ERROR_M)
        self.assertLess(max(vertical), MAX_VERTICAL_ERROR_M)
        self.assertLess(yaw, MAX_MAPPED_YAW_ERROR_DEG)
        self.assertGreater(odom_errors[-1], 3 * errors[-1], "mapping removed most of the odometry drift")

        # TF camera_init -> aft_mapped, at the stamps of the answers.
        for i in (0, FRAMES // 2, FRAMES - 1):
            try:
                tf = self.tf_buffer.lookup_transform("camera_init", "aft_mapped", self.stamps[i], rospy.Duration(2.0))
            except tf2_ros.TransformException as e:
                self.fail("no TF camera_init -> aft_mapped at frame %d: %s" % (i, e))
            t, q = tf.transform.translation, tf.transform.rotation
            self.assertAlmostEqual(t.x, mapped[i][0, 3], places=4)
            self.assertAlmostEqual(t.y, mapped[i][1, 3], places=4)
            self.assertAlmostEqual(t.z, mapped[i][2, 3], places=4)
            np.testing.assert_allclose(u.quat_to_rot(q.x, q.y, q.z, q.w), mapped[i][:3, :3], atol=1e-5)

        for topic, collector in extra.items():
            self.assertGreater(collector.count, 0, "nothing on %s" % topic)
            last = collector.by_stamp[max(collector.by_stamp)]
            self.assertEqual(last.header.frame_id, "camera_init", topic)
            if topic == "/aft_mapped_path":
                self.assertEqual(len(last.poses), FRAMES)
                self.assertEqual(collector.count, FRAMES)
            else:
                self.assertEqual(u.cloud_problems(last), [], topic)
        self.assertEqual(extra["/velodyne_cloud_registered"].count, FRAMES)
        self.assertEqual(extra["/velodyne_cloud_registered"].by_stamp[self.stamps[-1].to_nsec()].width,
                         self.features[-1]["full"].shape[0], "every point of the frame registered")
        # laser_cloud_surround every surround_every (5) frames
        self.assertEqual(extra["/laser_cloud_surround"].count, FRAMES // 5)
        # laser_cloud_map: at most every map_publish_period (2 s of stamps): frames 0 and 20
        self.assertEqual(sorted(extra["/laser_cloud_map"].by_stamp),
                         [self.stamps[0].to_nsec(), self.stamps[20].to_nsec()])
        type(self).map_cloud_points = extra["/laser_cloud_map"].by_stamp[self.stamps[20].to_nsec()].width
        for c in extra.values():
            c.unregister()

    def test_2_save_map(self):
        save = self.service("save_map", SaveMap)
        path = self.path("map.pcd")
        response = save(path)
        self.assertTrue(response.success, response.message)
        self.assertTrue(os.path.isfile(path))
        points, header = u.pcd_points(path)
        print("save_map: %d points (%s)" % (points, response.message), flush=True)
        self.assertIn(str(points), response.message)
        self.assertTrue(header["FIELDS"].startswith("x y z"), header["FIELDS"])
        self.assertEqual(header["DATA"], "binary")
        # the map only grows here: at least what laser_cloud_map showed at frame 20
        self.assertGreaterEqual(points, getattr(self, "map_cloud_points", 1))
        self.assertGreater(points, 1000)

    def test_3_save_trajectory(self):
        save = self.service("save_trajectory", SaveTrajectory)
        kitti, tum = self.path("trajectory.txt"), self.path("trajectory.tum")
        r = save(kitti, "kitti")
        self.assertTrue(r.success, r.message)
        rows = u.read_kitti(kitti)
        self.assertEqual(len(rows), FRAMES, "one KITTI row per mapped frame")
        np.testing.assert_allclose(rows[0], np.eye(4), atol=1e-9)
        answers = [u.pose_to_matrix(self.mapped.by_stamp[s.to_nsec()].pose.pose) for s in self.stamps]
        for row, answer in zip(rows, answers):  # relative to the first answer (identity here)
            np.testing.assert_allclose(row[:3, 3], (np.linalg.inv(answers[0]) @ answer)[:3, 3], atol=1e-4)
        r = save(tum, "tum")
        self.assertTrue(r.success, r.message)
        with open(tum) as f:
            lines = [line.split() for line in f if line.strip() and not line.startswith("#")]
        self.assertEqual(len(lines), FRAMES)
        self.assertTrue(all(len(line) == 8 for line in lines), "TUM rows: stamp x y z qx qy qz qw")
        np.testing.assert_allclose([float(line[0]) for line in lines], [s.to_sec() for s in self.stamps], atol=1e-6)
        r = save(self.path("trajectory.xyz"), "xyz")
        self.assertFalse(r.success, "an unknown format was accepted")
        self.assertFalse(os.path.exists(self.path("trajectory.xyz")))

    def test_4_reset(self):
        before, _ = u.pcd_points(self.path("map.pcd")) if os.path.exists(self.path("map.pcd")) else (None, None)
        r = self.service("reset", Trigger)()
        self.assertTrue(r.success, r.message)
        # Continue the drive (stamps go on) after the reset: frames 10..14 again, 3.0 s later.
        stamps = [self.base + rospy.Duration(3.0 + 0.1 * k) for k in range(5)]
        answers = self.feed(range(10, 15), stamps, self.odom)
        self.assertTrue(all(a is not None for a in answers), "frames after ~reset unanswered")
        # A new map: the first frame after the reset keeps its odometry pose (no correction, empty map).
        np.testing.assert_allclose(u.pose_to_matrix(answers[0].pose.pose), self.odom[10], atol=1e-5,
                                   err_msg="the first pose after ~reset is the odometry pose")
        high = self.high.wait_for(stamps[0].to_nsec(), 10.0)
        self.assertIsNotNone(high)
        gap = np.linalg.norm(u.pose_to_matrix(high.pose.pose)[:3, 3] - self.odom[10][:3, 3])
        print("first frame after ~reset: high-rate answer %.3f m from the mapped answer" % gap, flush=True)
        type(self).reset_high_rate_gap = gap
        r = self.service("save_trajectory", SaveTrajectory)(self.path("after_reset.txt"), "kitti")
        self.assertTrue(r.success, r.message)
        self.assertEqual(len(u.read_kitti(self.path("after_reset.txt"))), 5, "the trajectory restarted")
        r = self.service("save_map", SaveMap)(self.path("after_reset.pcd"))
        self.assertTrue(r.success, r.message)
        after, _ = u.pcd_points(self.path("after_reset.pcd"))
        if before is not None:
            self.assertLess(after, before, "the map restarted (%d points, %d before the reset)" % (after, before))
        # the new map is consistent with itself: consecutive poses follow the odometry motion
        m = [u.pose_to_matrix(a.pose.pose) for a in answers]
        for i in range(1, len(m)):
            step = np.linalg.norm((np.linalg.inv(m[i - 1]) @ m[i])[:3, 3])
            self.assertAlmostEqual(step, 0.5, delta=0.1)


    def test_5_high_rate_answer_after_reset(self):
        """After ~reset the high-rate answer of the first frame must not use the old map's correction."""
        gap = getattr(self, "reset_high_rate_gap", None)
        if gap is None:
            self.skipTest("test_4_reset did not get that far")
        self.assertLess(gap, MAX_HIGH_RATE_GAP_M,
                        "aft_mapped_to_init_high_frec of the first frame after ~reset is %.3f m away from its "
                        "aft_mapped_to_init: it was corrected with the correction of the map that was reset" % gap)

    def test_6_save_map_unwritable_path(self):
        """SaveMap promises success=false and a message when the file cannot be written."""
        save = self.service("save_map", SaveMap)
        try:
            response = save("/nonexistent_directory/aloam/map.pcd")
        except rospy.ServiceException as e:
            self.fail("~save_map to an unwritable path failed the service call instead of answering "
                      "success=false: %s" % e)
        self.assertFalse(response.success, "saving to a missing directory reported success")
        self.assertIn("/nonexistent_directory/aloam/map.pcd", response.message)
        # and the service still works afterwards
        self.assertTrue(save(self.path("map_again.pcd")).success)


if __name__ == "__main__":
    rospy.init_node("test_nodelet_mapping")
    rostest.rosrun("aloam_nodelet", "nodelet_mapping", TestLaserMappingNodelet)
