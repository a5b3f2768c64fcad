#!/usr/bin/env python3
"""ScanRegistration alone in a nodelet manager (nodelet_registration.test), fed synthetic VLP-16 sweeps.

- laser_features (read here as aloam_nodelet/FeatureClouds) comes once per sweep, with the input's
  stamps, in order (the rate is printed, not asserted: a loaded machine sets it); its clouds are well-formed, ring-ordered, with sweep times, and hold the
  feature classes in the expected relation (sharp <= less_sharp, flat <= less_flat <= full <= input)
- the visualisation clouds (laser_cloud_sharp, _less_sharp, _flat, _less_flat, velodyne_cloud_2) are
  advertised, reach a subscriber for every sweep sent after it subscribed (none from before), and are
  well-formed (fields x y z intensity time ring, width*height*point_step == len(data), finite values),
  with the same point counts as the matching FeatureClouds
- a cloud without ring and time fields is still registered (rings from the elevation, VLP-16 preset)
- unusable clouds (no z field, too few points) give no output and do not stop the nodelet
"""
import time

import numpy as np
import rospy
import rostest
from sensor_msgs.msg import PointCloud2

from aloam_nodelet.msg import FeatureClouds

import aloam_rostest_utils as u

RATE_HZ = 10.0  # at most; each sweep also waits for its features, so none is lost on a slow machine
# Only a lost message runs into this (a sweep takes milliseconds).
ANSWER_TIMEOUT = 30.0
VIS_TOPICS = ("laser_cloud_sharp", "laser_cloud_less_sharp", "laser_cloud_flat", "laser_cloud_less_flat",
              "velodyne_cloud_2")
FEATURE_OF = {"laser_cloud_sharp": "sharp", "laser_cloud_less_sharp": "less_sharp", "laser_cloud_flat": "flat",
              "laser_cloud_less_flat": "less_flat", "velodyne_cloud_2": "full"}


class TestScanRegistrationNodelet(u.ScratchTestCase):

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        street, drive = u.Street(), u.Drive(speed=5.0)
        cls.sweeps = [u.simulate_sweep(street, drive, k) for k in range(12)]
        cls.next_stamp = rospy.Time(2000)
        cls.pub = rospy.Publisher("/velodyne_points", PointCloud2, queue_size=5)
        missing = u.wait_for_graph(subscribed=["/velodyne_points"], published=["/laser_features"], timeout=40)
        assert not missing, "scan registration not up: %s" % missing
        cls.features = u.StampCollector("/laser_features", FeatureClouds, keep=True)
        assert u.wait_connected(cls.pub) and u.wait_connected(cls.features.sub), "no connection to the nodelet"

    def stamp(self):
        s = type(self).next_stamp
        type(self).next_stamp = s + rospy.Duration(0.1)
        return s

    def publish_at_rate(self, count, offset=0):
        """Publishes `count` sweeps at RATE_HZ at most, each after the features of the one before (the input
        queue holds one sweep: a faster feed would drop sweeps whenever the machine is busy); returns
        [(wall time, stamp ns, input point count)]."""
        sent = []
        rate = rospy.Rate(RATE_HZ)
        for i in range(count):
            pts = self.sweeps[(offset + i) % len(self.sweeps)]
            msg = u.cloud_message(pts, self.stamp())
            self.pub.publish(msg)
            sent.append((time.time(), msg.header.stamp.to_nsec(), pts.shape[0]))
            self.features.wait_for(msg.header.stamp.to_nsec(), ANSWER_TIMEOUT)
            rate.sleep()
        return sent

    def check_features(self, msg, input_points):
        self.assertAlmostEqual(msg.scan_period, 0.1, places=6)
        self.assertTrue(msg.has_time, "has_time false although the input has a time field")
        counts = {}
        for name in ("sharp", "less_sharp", "flat", "less_flat", "full"):
            cloud = getattr(msg, name)
            problems = u.cloud_problems(cloud, min_points=1)
            self.assertEqual(problems, [], "FeatureClouds.%s: %s" % (name, problems))
            self.assertEqual(cloud.header.stamp, msg.header.stamp, "FeatureClouds.%s stamp" % name)
            arr = u.cloud_array(cloud)
            counts[name] = arr.shape[0]
            self.assertTrue(np.all(np.diff(arr["ring"].astype(int)) >= 0), "%s not ordered by ring" % name)
            self.assertTrue(np.all((arr["time"] >= -1e-4) & (arr["time"] <= 0.1 + 1e-4)),
                            "%s times outside the sweep: %.4f..%.4f" % (name, arr["time"].min(), arr["time"].max()))
            self.assertLess(int(arr["ring"].max()), 16, "%s has a ring beyond 16 beams" % name)
        self.assertLessEqual(counts["sharp"], counts["less_sharp"])
        self.assertLessEqual(counts["flat"], counts["less_flat"])
        self.assertLessEqual(counts["less_flat"], counts["full"])
        self.assertLessEqual(counts["full"], input_points)
        self.assertGreater(counts["full"], 0.9 * input_points, "most returns of the synthetic sweep are usable")
        self.assertGreater(counts["sharp"], 20)
        self.assertGreater(counts["flat"], 50)
        return counts

    def check_rate(self, sent, collector, what):
        """Every sent stamp arrived once and in order; prints the input and output rates."""
        sent_stamps = [s for _, s, _ in sent]
        deadline = time.time() + ANSWER_TIMEOUT
        while time.time() < deadline and not set(sent_stamps) <= set(collector.stamps()):
            time.sleep(0.05)
        got = [s for s in collector.stamps() if s in set(sent_stamps)]
        self.assertEqual(len(got), len(set(got)), "%s: duplicate stamps" % what)
        self.assertEqual(got, sorted(got), "%s: stamps out of order" % what)
        self.assertEqual(len(got), len(sent), "%s: %d of %d sweeps answered" % (what, len(got), len(sent)))
        arrivals = [t for t, s in collector.arrivals if s in set(sent_stamps)]
        in_rate = (len(sent) - 1) / (sent[-1][0] - sent[0][0])
        out_rate = (len(arrivals) - 1) / (arrivals[-1] - arrivals[0])
        # A figure, not a bound: how fast a sweep is turned around depends on the machine's load.
        print("%s: %d of %d sweeps, input %.2f Hz, output %.2f Hz" % (what, len(got), len(sent), in_rate, out_rate),
              flush=True)
        return got

    def test_1_features_at_input_rate(self):
        sent = self.publish_at_rate(30)
        got = self.check_rate(sent, self.features, "laser_features")
        inputs = {s: n for _, s, n in sent}
        for stamp in got:
            msg = self.features.by_stamp[stamp]
            self.assertEqual(msg.header.stamp.to_nsec(), stamp)
            self.assertEqual(msg.header.frame_id, "velodyne", "the input frame is kept")
            self.check_features(msg, inputs[stamp])
        # The visualisation topics are advertised although nobody listens yet.
        for topic in VIS_TOPICS:
            pubs, _ = u.topic_state("/" + topic)
            self.assertTrue(pubs, "/%s is not advertised" % topic)

    def test_2_visualisation_clouds_when_subscribed(self):
        before = set(self.features.stamps())  # every sweep sent before anyone subscribed
        vis = {t: u.StampCollector("/" + t, PointCloud2) for t in VIS_TOPICS}
        for t, c in vis.items():
            self.assertTrue(u.wait_connected(c.sub), "no connection on /%s" % t)
        sent = self.publish_at_rate(20, offset=3)
        for topic, collector in vis.items():
            got = self.check_rate(sent, collector, topic)
            self.assertFalse(set(collector.stamps()) & before,
                             "/%s delivered sweeps sent before it was subscribed" % topic)
            for stamp in got:
                cloud = collector.by_stamp[stamp]
                problems = u.cloud_problems(cloud, min_points=1)
                self.assertEqual(problems, [], "/%s: %s" % (topic, problems))
                self.assertEqual(cloud.header.frame_id, "velodyne")
                features = self.features.by_stamp.get(stamp)
                self.assertIsNotNone(features, "no laser_features for a sweep on /%s" % topic)
                self.assertEqual(cloud.width * cloud.height, getattr(features, FEATURE_OF[topic]).width,
                                 "/%s and laser_features.%s differ" % (topic, FEATURE_OF[topic]))
        for c in vis.values():
            c.unregister()

    def test_3_no_ring_no_time_fields(self):
        pts = self.sweeps[5]
        plain = np.zeros(pts.shape[0], dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4")])
        for name in plain.dtype.names:
            plain[name] = pts[name]
        msg = u.cloud_message(plain, self.stamp())
        self.pub.publish(msg)
        out = self.features.wait_for(msg.header.stamp.to_nsec(), 5.0)
        self.assertIsNotNone(out, "no laser_features for a cloud with x y z intensity only")
        full = u.cloud_array(out.full)
        self.assertGreater(full.shape[0], 0.9 * pts.shape[0], "rings from elevation lost points")
        self.assertEqual(len(np.unique(full["ring"])), 16, "all 16 VLP-16 rings found from elevations")
        self.assertGreater(out.sharp.width, 20)

    def test_4_float64_and_organized_input(self):
        """float64 coordinates and an organized cloud (rings x azimuth steps, NaN holes) give the same
        features as the packed float32 cloud of the same sweep."""
        pts = self.sweeps[7]
        reference = u.cloud_message(pts, self.stamp())
        wide = np.zeros(pts.shape[0], dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("intensity", "<f4"),
                                             ("ring", "<u2"), ("time", "<f4")])
        for name in pts.dtype.names:
            wide[name] = pts[name]
        float64 = u.cloud_message(wide, self.stamp())
        steps = 1800
        grid = np.zeros((16, steps), dtype=u.POINT_DTYPE)
        for name in ("x", "y", "z", "intensity", "time"):
            grid[name] = np.nan
        column = np.rint(pts["time"] / u.SCAN_PERIOD * steps).astype(int)
        grid[pts["ring"].astype(int), column] = pts
        organized = u.cloud_message(grid.reshape(-1), self.stamp())
        organized.height, organized.width = 16, steps
        organized.row_step = steps * organized.point_step
        organized.is_dense = False
        results = {}
        for label, msg in (("float32", reference), ("float64", float64), ("organized", organized)):
            self.pub.publish(msg)
            out = self.features.wait_for(msg.header.stamp.to_nsec(), 5.0)
            self.assertIsNotNone(out, "no laser_features for the %s cloud" % label)
            results[label] = {name: getattr(out, name).width for name in ("sharp", "less_sharp", "flat", "less_flat",
                                                                          "full")}
            time.sleep(0.12)
        print("features of one sweep: %s" % results, flush=True)
        self.assertEqual(results["float32"]["full"], pts.shape[0])
        self.assertEqual(results["float64"], results["float32"], "float64 coordinates")
        self.assertEqual(results["organized"]["full"], results["float32"]["full"], "NaN holes dropped, no point lost")

    def test_5_unusable_clouds_skipped(self):
        pts = self.sweeps[2]
        no_z = np.zeros(pts.shape[0], dtype=[("x", "<f4"), ("y", "<f4"), ("intensity", "<f4")])
        no_z["x"], no_z["y"] = pts["x"], pts["y"]
        bad = [u.cloud_message(no_z, self.stamp()), u.cloud_message(pts[:10], self.stamp()),
               u.cloud_message(pts[:0], self.stamp())]
        for msg in bad:
            self.pub.publish(msg)
            time.sleep(0.15)
        good = u.cloud_message(pts, self.stamp())
        self.pub.publish(good)
        self.assertIsNotNone(self.features.wait_for(good.header.stamp.to_nsec(), 5.0),
                             "the nodelet stopped answering after unusable clouds")
        time.sleep(0.3)
        for msg in bad:
            self.assertNotIn(msg.header.stamp.to_nsec(), self.features.by_stamp,
                             "features published for an unusable cloud (%d points, fields %s)"
                             % (msg.width, [f.name for f in msg.fields]))


if __name__ == "__main__":
    rospy.init_node("test_nodelet_registration")
    rostest.rosrun("aloam_nodelet", "nodelet_registration", TestScanRegistrationNodelet)
