#!/usr/bin/env python3
"""LaserOdometry alone in a nodelet manager (nodelet_odometry.test), fed aloam_nodelet/FeatureClouds built
here: synthetic VLP-16 sweeps of a moving sensor (motion distortion, deskewing on as config/VLP16.yaml
sets it), split into LOAM features by aloam_rostest_utils.extract_features.

- laser_odom_to_init: one per input (the rate is printed, not asserted: a loaded machine sets it), with the
  input stamps, frame camera_init ->
  laser_odom, finite poses with unit quaternions, identity first; the trajectory follows the simulated
  drive (final position error and per-step error bounded)
- laser_odom_frame (as aloam_nodelet/OdometryFrame): same stamps and poses, status INITIALIZED then OK,
  only the first sweep distorted, well-formed clouds
- laser_odom_path, laser_cloud_corner_last, laser_cloud_surf_last, velodyne_cloud_3 when subscribed
- ~reset starts a new trajectory at identity; a stamp jumping back by more than 1 s does too
"""
import math
import time

import numpy as np
import rospy
import rostest
from nav_msgs.msg import Odometry, Path
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Header
from std_srvs.srv import Trigger

from aloam_nodelet.msg import FeatureClouds, OdometryFrame

import aloam_rostest_utils as u

SWEEPS = 30
RATE_HZ = 10.0  # at most; each sweep also waits for its answer, so none is lost on a slow machine
# Only a lost message runs into this (a sweep takes milliseconds).
ANSWER_TIMEOUT = 30.0
# Scan-to-scan odometry alone drifts on 16 beams (mostly a slow climb in z, which mapping removes).
# Measured here: final error 0.71 m over 14.5 m (4.9 %), worst step error 0.038 m, yaw error 0.08 deg;
# the same sweeps through the real ScanRegistration give 0.79 m (5.4 %).
MAX_FINAL_ERROR_FRACTION = 0.08   # of the distance driven
MAX_STEP_ERROR_M = 0.08           # per sweep (the sensor moves 0.5 m per sweep)
MAX_YAW_ERROR_DEG = 1.0


def feature_message(features, stamp):
    msg = FeatureClouds()
    msg.header.stamp = stamp
    msg.header.frame_id = "velodyne"
    msg.scan_period = u.SCAN_PERIOD
    msg.has_time = True
    for name in ("sharp", "less_sharp", "flat", "less_flat", "full"):
        setattr(msg, name, u.cloud_message(features[name], stamp))
    return msg


class TestLaserOdometryNodelet(u.ScratchTestCase):

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        street, cls.drive = u.Street(), u.Drive(speed=5.0)
        cls.messages = []
        base = rospy.Time(3000)
        for k in range(SWEEPS):
            pts = u.simulate_sweep(street, cls.drive, k, moving=True)
            cls.messages.append(feature_message(u.extract_features(pts), base + rospy.Duration(0.1 * k)))
        cls.truth = u.sweep_end_poses(cls.drive, SWEEPS)
        cls.pub = rospy.Publisher("/laser_features", FeatureClouds, queue_size=5)
        missing = u.wait_for_graph(subscribed=["/laser_features"], published=["/laser_odom_to_init"], timeout=40)
        assert not missing, "laser odometry not up: %s" % missing
        cls.odom = u.StampCollector("/laser_odom_to_init", Odometry)
        cls.frames = u.StampCollector("/laser_odom_frame", OdometryFrame)
        assert u.wait_connected(cls.pub) and u.wait_connected(cls.odom.sub) and u.wait_connected(cls.frames.sub)

    def send_at_rate(self, messages):
        sent = []
        rate = rospy.Rate(RATE_HZ)
        for msg in messages:
            self.pub.publish(msg)
            sent.append((time.time(), msg.header.stamp.to_nsec()))
            # The input queue holds two sweeps: a feed that does not wait would drop sweeps on a busy machine.
            self.odom.wait_for(msg.header.stamp.to_nsec(), ANSWER_TIMEOUT)
            rate.sleep()
        return sent

    def test_1_odometry_of_the_drive(self):
        extras = {"/laser_odom_path": Path, "/laser_cloud_corner_last": PointCloud2,
                  "/laser_cloud_surf_last": PointCloud2, "/velodyne_cloud_3": PointCloud2}
        extra = u.connected_collectors(self, extras)
        sent = self.send_at_rate(self.messages)
        stamps = [s for _, s in sent]
        got = [s for s in self.odom.stamps() if s in set(stamps)]
        self.assertEqual(got, stamps, "laser_odom_to_init: one answer per input, in order, with its stamp")
        arrivals = [t for t, s in self.odom.arrivals if s in set(stamps)]
        in_rate = (len(sent) - 1) / (sent[-1][0] - sent[0][0])
        out_rate = (len(arrivals) - 1) / (arrivals[-1] - arrivals[0])
        # A figure, not a bound: how fast a sweep is turned around depends on the machine's load.
        print("laser_odom_to_init: %d of %d, input %.2f Hz, output %.2f Hz" % (len(got), len(sent), in_rate,
                                                                               out_rate), flush=True)

        poses = []
        for stamp in stamps:
            odom = self.odom.by_stamp[stamp]
            self.assertEqual(odom.header.frame_id, "camera_init")
            self.assertEqual(odom.child_frame_id, "laser_odom")
            self.assertTrue(u.pose_is_finite(odom), "non-finite pose or non-unit quaternion: %s" % odom.pose.pose)
            poses.append(u.pose_to_matrix(odom.pose.pose))
        np.testing.assert_allclose(poses[0], np.eye(4), atol=1e-9, err_msg="the first pose is the origin")

        # Against the simulated drive, both relative to the first sweep's end.
        truth = [np.linalg.inv(self.truth[0]) @ m for m in self.truth]
        errors = [np.linalg.norm(p[:3, 3] - t[:3, 3]) for p, t in zip(poses, truth)]
        steps = [np.linalg.norm((np.linalg.inv(poses[i - 1]) @ poses[i])[:3, 3]
                                - (np.linalg.inv(truth[i - 1]) @ truth[i])[:3, 3]) for i in range(1, len(poses))]
        distance = sum(np.linalg.norm(truth[i][:3, 3] - truth[i - 1][:3, 3]) for i in range(1, len(truth)))
        yaw_error = math.degrees(abs(math.atan2(poses[-1][1, 0], poses[-1][0, 0])
                                     - math.atan2(truth[-1][1, 0], truth[-1][0, 0])))
        print("odometry over %.1f m: final error %.3f m (%.2f %%), max step error %.3f m, final yaw error %.2f deg"
              % (distance, errors[-1], 100 * errors[-1] / distance, max(steps), yaw_error), flush=True)
        self.assertLess(errors[-1], MAX_FINAL_ERROR_FRACTION * distance)
        self.assertLess(max(steps), MAX_STEP_ERROR_M)
        self.assertLess(yaw_error, MAX_YAW_ERROR_DEG)

        # The internal output, read as its wire message.
        for i, stamp in enumerate(stamps):
            frame = self.frames.wait_for(stamp, ANSWER_TIMEOUT)
            self.assertIsNotNone(frame, "no laser_odom_frame for sweep %d" % i)
            self.assertEqual(frame.header.frame_id, "camera_init")
            self.assertEqual(frame.child_frame_id, "laser_odom")
            self.assertEqual(frame.sensor_frame_id, "velodyne", "the input clouds' frame is passed on")
            np.testing.assert_allclose(u.pose_to_matrix(frame.pose), poses[i], atol=1e-6)
            self.assertEqual(frame.status, OdometryFrame.STATUS_INITIALIZED if i == 0 else OdometryFrame.STATUS_OK,
                             "sweep %d status %d (%d edge, %d plane matches)" % (i, frame.status, frame.corner_matches,
                                                                                frame.plane_matches))
            self.assertEqual(frame.distorted, i == 0, "only the first sweep (motion unknown) is distorted")
            for name in ("corners", "surfs", "full"):
                problems = u.cloud_problems(getattr(frame, name))
                self.assertEqual(problems, [], "OdometryFrame.%s of sweep %d: %s" % (name, i, problems))
            if i > 0:
                self.assertGreater(frame.corner_matches, 10)
                self.assertGreater(frame.plane_matches, 100)

        for topic, collector in extra.items():
            self.assertGreaterEqual(len(set(collector.stamps()) & set(stamps)), len(stamps) - 1,
                                    "%s: %d messages for %d sweeps" % (topic, collector.count, len(stamps)))
            last = collector.by_stamp[max(collector.by_stamp)]
            if topic == "/laser_odom_path":
                self.assertEqual(last.header.frame_id, "camera_init")
                self.assertEqual(len(last.poses), len(stamps), "the path holds every pose")
                np.testing.assert_allclose(u.pose_to_matrix(last.poses[-1].pose), poses[-1], atol=1e-6)
            else:
                self.assertEqual(u.cloud_problems(last), [], topic)
            collector.unregister()

    def test_2_reset_service(self):
        service = "/laser_odometry/reset"
        self.assertTrue(u.wait_for_service(service, 10), "%s not advertised" % service)
        before = feature_message_copy(self.messages[10], rospy.Time(3010))
        self.pub.publish(before)
        answer = self.odom.wait_for(before.header.stamp.to_nsec(), ANSWER_TIMEOUT)
        self.assertIsNotNone(answer)
        response = rospy.ServiceProxy(service, Trigger)()
        self.assertTrue(response.success, response.message)
        after = feature_message_copy(self.messages[12], rospy.Time(3010.1))
        self.pub.publish(after)
        answer = self.odom.wait_for(after.header.stamp.to_nsec(), ANSWER_TIMEOUT)
        self.assertIsNotNone(answer, "no answer after ~reset")
        np.testing.assert_allclose(u.pose_to_matrix(answer.pose.pose), np.eye(4), atol=1e-9,
                                   err_msg="after ~reset the next sweep starts a new trajectory at the origin")
        frame = self.frames.wait_for(after.header.stamp.to_nsec(), ANSWER_TIMEOUT)
        self.assertEqual(frame.status, OdometryFrame.STATUS_INITIALIZED)
        # and it continues from there: the next sweep moves about 0.5 m
        nxt = feature_message_copy(self.messages[13], rospy.Time(3010.2))
        self.pub.publish(nxt)
        answer = self.odom.wait_for(nxt.header.stamp.to_nsec(), ANSWER_TIMEOUT)
        self.assertIsNotNone(answer)
        moved = np.linalg.norm(u.pose_to_matrix(answer.pose.pose)[:3, 3])
        self.assertAlmostEqual(moved, 0.5, delta=0.1, msg="motion after the reset")

    def test_3_time_jump_back_resets(self):
        first = feature_message_copy(self.messages[20], rospy.Time(4000))
        second = feature_message_copy(self.messages[21], rospy.Time(4000.1))
        for msg in (first, second):
            self.pub.publish(msg)
            self.assertIsNotNone(self.odom.wait_for(msg.header.stamp.to_nsec(), ANSWER_TIMEOUT))
            time.sleep(0.05)
        back = feature_message_copy(self.messages[22], rospy.Time(3990))  # 10 s back: a looping bag
        self.pub.publish(back)
        answer = self.odom.wait_for(back.header.stamp.to_nsec(), ANSWER_TIMEOUT)
        self.assertIsNotNone(answer)
        np.testing.assert_allclose(u.pose_to_matrix(answer.pose.pose), np.eye(4), atol=1e-9,
                                   err_msg="a stamp 10 s back restarts the trajectory")


def feature_message_copy(msg, stamp):
    """The same features under a new stamp."""
    out = FeatureClouds()
    out.header.stamp = stamp
    out.header.frame_id = msg.header.frame_id
    out.scan_period, out.has_time = msg.scan_period, msg.has_time
    for name in ("sharp", "less_sharp", "flat", "less_flat", "full"):
        cloud = getattr(msg, name)
        copy = PointCloud2(header=Header(frame_id=cloud.header.frame_id, stamp=stamp), height=cloud.height,
                           width=cloud.width, fields=cloud.fields, is_bigendian=cloud.is_bigendian,
                           point_step=cloud.point_step, row_step=cloud.row_step, data=cloud.data,
                           is_dense=cloud.is_dense)
        setattr(out, name, copy)
    return out


if __name__ == "__main__":
    rospy.init_node("test_nodelet_odometry")
    rostest.rosrun("aloam_nodelet", "nodelet_odometry", TestLaserOdometryNodelet)
