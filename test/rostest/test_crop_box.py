#!/usr/bin/env python3
"""crop_box:=true (crop_box.test): pcl_ros's CropBox nodelet runs in the pipeline's own manager in front of
registration, and the points inside its box never reach registration.

Both pipelines get the same simulated VLP-16 sweeps of a street, each with a robot body added: a dense
block of returns inside the box of crop_box_test.yaml (0.3-1.4 m from the sensor, beyond registration's
0.3 m minimum range, so registration would keep them). Registration's velodyne_cloud_2 (every point it
used) is read from both:
- "plain" (no filter, the control) uses body points: they would reach LOAM without the filter,
- "cropped" uses none, in any sweep, yet about as many points outside the box as "plain",
- the CropBox nodelet is loaded in /cropped/aloam_manager (zero-copy), and the pipeline still tracks.
"""
import numpy as np
import rospy
import rostest
from nav_msgs.msg import Odometry
from nodelet.srv import NodeletList
from sensor_msgs.msg import PointCloud2

import aloam_rostest_utils as u

SWEEPS = 12
BOX_MIN = np.array([-1.2, -0.5, -0.9])
BOX_MAX = np.array([-0.2, 0.5, -0.1])


def body_points(rng, count=1500):
    """Returns of a robot body strictly inside the box (a margin of 2 cm), with ring and time fields."""
    pts = np.zeros(count, dtype=u.POINT_DTYPE)
    xyz = rng.uniform(BOX_MIN + 0.02, BOX_MAX - 0.02, size=(count, 3))
    pts["x"], pts["y"], pts["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    pts["intensity"] = 80.0
    elevation = np.degrees(np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1])))
    pts["ring"] = np.clip(np.round((elevation + 15.0) / 2.0), 0, 15).astype(np.uint16)
    azimuth = np.mod(np.arctan2(xyz[:, 1], xyz[:, 0]), 2 * np.pi)
    pts["time"] = azimuth / (2 * np.pi) * u.SCAN_PERIOD
    return pts


def inside(cloud):
    xyz = np.stack([cloud["x"], cloud["y"], cloud["z"]], axis=1)
    return np.all((xyz >= BOX_MIN) & (xyz <= BOX_MAX), axis=1)


class TestCropBox(u.ScratchTestCase):

    def test_points_inside_the_box_never_reach_registration(self):
        pubs = {ns: rospy.Publisher("/%s/velodyne_points" % ns, PointCloud2, queue_size=SWEEPS) for ns in
                ("cropped", "plain")}
        used = {ns: u.StampCollector("/%s/velodyne_cloud_2" % ns, PointCloud2, keep=True) for ns in pubs}
        odometry = u.StampCollector("/cropped/aft_mapped_to_init", Odometry, keep=True)
        missing = u.wait_for_graph(subscribed=["/cropped/velodyne_points", "/cropped/velodyne_points_cropped",
                                               "/plain/velodyne_points"],
                                   published=["/cropped/velodyne_cloud_2", "/plain/velodyne_cloud_2"], timeout=60)
        self.assertFalse(missing, "pipelines not up: %s" % missing)
        for collector in list(used.values()) + [odometry]:
            self.assertTrue(u.wait_connected(collector.sub))
        for pub in pubs.values():
            self.assertTrue(u.wait_connected(pub))

        rospy.wait_for_service("/cropped/aloam_manager/list", timeout=30)
        loaded = rospy.ServiceProxy("/cropped/aloam_manager/list", NodeletList)().nodelets
        self.assertIn("/cropped/crop_box", loaded, "CropBox is not in the pipeline's manager: %s" % loaded)

        street, drive = u.Street(), u.Drive(speed=5.0)
        rng = np.random.RandomState(7)
        stamps = []
        for k in range(SWEEPS):
            sweep = np.concatenate([u.simulate_sweep(street, drive, k), body_points(rng)])
            sweep = sweep[np.argsort(sweep["time"], kind="stable")]
            msg = u.cloud_message(sweep, rospy.Time(3000) + rospy.Duration(0.1 * k))
            for pub in pubs.values():
                pub.publish(msg)
            stamps.append(msg.header.stamp.to_nsec())
            for ns in pubs:
                self.assertIsNotNone(used[ns].wait_for(stamps[-1], 20.0), "%s: no velodyne_cloud_2 for sweep %d"
                                     % (ns, k))
        self.assertGreaterEqual(odometry.wait_count(SWEEPS - 1, 30.0), SWEEPS - 1,
                                "the cropped pipeline stopped answering")

        counts = {}
        for ns in pubs:
            clouds = [u.cloud_array(m) for m in used[ns].by_stamp.values()]
            counts[ns] = (sum(int(inside(c).sum()) for c in clouds), sum(int((~inside(c)).sum()) for c in clouds))
        print("RESULT velodyne_cloud_2 over %d sweeps: plain %d points inside the box, %d outside; cropped %d "
              "inside, %d outside" % (SWEEPS, counts["plain"][0], counts["plain"][1], counts["cropped"][0],
                                      counts["cropped"][1]), flush=True)
        self.assertGreater(counts["plain"][0], 100 * SWEEPS, "the control pipeline should use the body points")
        self.assertEqual(counts["cropped"][0], 0, "points inside the box reached registration")
        self.assertGreater(counts["cropped"][1], 0.9 * counts["plain"][1], "the filter removed points outside it")


if __name__ == "__main__":
    rospy.init_node("test_crop_box")
    rostest.rosrun("aloam_nodelet", "crop_box", TestCropBox)
