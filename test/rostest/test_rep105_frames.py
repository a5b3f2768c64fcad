#!/usr/bin/env python3
"""aloam.launch tf_mode:=rep105 (rep105_frames.test): REP 105 frames from the mapping nodelet.

With a static base_link -> velodyne extrinsic published here:
- map -> odom -> base_link is published for every sweep; camera_init -> aft_mapped is not
- odom and map are base_link at the first sweep: odom -> base_link starts at identity
- map -> base_link equals the mapped sensor pose seen through the extrinsic, T_bs * P * T_bs^-1, at every
  answered stamp (so map -> odom carries the mapping correction, odom -> base_link the odometry)
"""
import time

import numpy as np
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import TransformStamped

import aloam_rostest_utils as u

SWEEPS = 20
# A sensor mounted 0.5 m ahead and 1.7 m above base_link, turned 0.1 rad: a non-trivial extrinsic.
EXTRINSIC_XYZ = (0.5, 0.0, 1.7)
EXTRINSIC_YAW = 0.1
MAX_POSITION_DIFF_M = 1e-3
MAX_ROTATION_DIFF = 1e-4  # Frobenius norm of the rotation difference


def wait_for_connections(publisher, count, timeout):
    deadline = time.time() + timeout
    while publisher.get_num_connections() < count and time.time() < deadline and not rospy.is_shutdown():
        time.sleep(0.05)
    return publisher.get_num_connections() >= count


def transform_matrix(t):
    m = np.eye(4)
    m[:3, :3] = u.quat_to_rot(t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w)
    m[:3, 3] = [t.translation.x, t.translation.y, t.translation.z]
    return m


class TestRep105Frames(u.ScratchTestCase):

    def test_map_odom_base_link(self):
        extrinsic = TransformStamped()
        extrinsic.header.frame_id = "base_link"
        extrinsic.child_frame_id = "velodyne"
        extrinsic.transform.translation.x, extrinsic.transform.translation.y, extrinsic.transform.translation.z = \
            EXTRINSIC_XYZ
        q = u.rot_to_quat(u.rot_z(EXTRINSIC_YAW))
        (extrinsic.transform.rotation.x, extrinsic.transform.rotation.y, extrinsic.transform.rotation.z,
         extrinsic.transform.rotation.w) = q
        static = tf2_ros.StaticTransformBroadcaster()
        static.sendTransform(extrinsic)
        base_from_sensor = transform_matrix(extrinsic.transform)

        buffer = tf2_ros.Buffer(cache_time=rospy.Duration(60.0))
        tf2_ros.TransformListener(buffer)
        bag, _ = u.make_test_bag(self.scratch, sweeps=SWEEPS, sensor="VLP16")
        clouds = u.read_bag_clouds(bag)
        replayer = u.Replayer(ns="", timeout=10.0)
        self.assertEqual(replayer.wait_ready(), [], "pipeline not wired")
        # The latched extrinsic reaches a subscriber as soon as it is connected: wait for the connections of
        # our own listener and of the manager (the mapping nodelet's listener) instead of a fixed sleep.
        self.assertTrue(wait_for_connections(static.pub_tf, 2, 30.0), "the extrinsic reached no nodelet")
        answers = replayer.play(clouds)
        self.assertEqual([i for i, a in enumerate(answers) if a is None], [], "unanswered sweeps")
        # The transforms of the last sweep leave after its answer: wait for them (only a loss runs out).
        last = answers[-1].header.stamp
        for frames in (("map", "odom"), ("odom", "base_link")):
            self.assertTrue(buffer.can_transform(frames[0], frames[1], last, rospy.Duration(30.0)),
                            "no %s -> %s at the last answered stamp" % frames)

        self.assertFalse(buffer.can_transform("camera_init", "aft_mapped", rospy.Time(0)),
                         "A-LOAM frames published in rep105 mode")
        first = answers[0].header.stamp
        odom_to_base = transform_matrix(buffer.lookup_transform("odom", "base_link", first).transform)
        np.testing.assert_allclose(odom_to_base, np.eye(4), atol=1e-6, err_msg="odom is not base_link at start")

        checked = 0
        for answer in answers[1:]:
            stamp = answer.header.stamp
            map_to_base = transform_matrix(buffer.lookup_transform("map", "base_link", stamp).transform)
            expected = base_from_sensor @ u.pose_to_matrix(answer.pose.pose) @ np.linalg.inv(base_from_sensor)
            position_diff = np.linalg.norm(map_to_base[:3, 3] - expected[:3, 3])
            rotation_diff = np.linalg.norm(map_to_base[:3, :3] - expected[:3, :3])
            self.assertLess(position_diff, MAX_POSITION_DIFF_M, "stamp %s" % stamp)
            self.assertLess(rotation_diff, MAX_ROTATION_DIFF, "stamp %s" % stamp)
            checked += 1
        print("map -> base_link matched the mapped pose through the extrinsic at %d stamps" % checked, flush=True)
        self.assertEqual(checked, SWEEPS - 1)


if __name__ == "__main__":
    rospy.init_node("test_rep105_frames")
    rostest.rosrun("aloam_nodelet", "rep105_frames", TestRep105Frames)
