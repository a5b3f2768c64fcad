#!/usr/bin/env python3
"""Unusual stamps into the running pipeline (time_handling.test).

A slow walk (1 m/s) through the test street, sweep by sweep, each waiting for its answer:
1. a duplicate (the next sweep's points under the last sweep's stamp) and a late sweep (stamped between two
   sweeps already answered) are dropped: no output carries them, each stamp already answered is answered
   exactly once, and scan registration counts one of each on /diagnostics;
2. then 7 sweeps go missing (0.8 s between stamps, more than laser_odometry's 5 periods): odometry counts a
   gap and restarts its motion prior, and the mapped poses after the gap continue the drive (each within
   MAX_POSITION_ERROR_M of the ground truth, the step across the gap within MAX_GAP_STEP_ERROR_M of the true
   one). No output is ever non-finite.
"""
import time

import numpy as np
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry

import aloam_rostest_utils as u

SPEED = 1.0  # m/s
BEFORE_GAP = 20   # sweeps 0..19
MISSING = 7       # sweeps 20..26 never sent
AFTER_GAP = 13    # sweeps 27..39
MAX_POSITION_ERROR_M = 0.3
MAX_GAP_STEP_ERROR_M = 0.15
DIAG_DUPLICATES = "stamps duplicate (dropped)"
DIAG_LATE = "stamps out of order (dropped)"
DIAG_GAPS = "time gaps (motion prediction restarted)"


class Diagnostics:
    """The latest value of every key of every status on /diagnostics."""

    def __init__(self):
        self.values = {}
        self.sub = rospy.Subscriber("/diagnostics", DiagnosticArray, self._cb, queue_size=50)

    def _cb(self, msg):
        for status in msg.status:
            self.values[status.name] = {kv.key: kv.value for kv in status.values}

    def value(self, node, key):
        for name, values in list(self.values.items()):
            if node in name and key in values:
                return values[key]
        return None

    def wait_value(self, node, key, expected, timeout=10.0):
        deadline = time.time() + timeout
        while time.time() < deadline and self.value(node, key) != expected:
            time.sleep(0.1)
        return self.value(node, key)


class TestTimeHandling(u.ScratchTestCase):

    def test_time_handling(self):
        street, drive = u.Street(), u.Drive(speed=SPEED)
        base = rospy.Time(5000)
        stamp = lambda k: base + rospy.Duration(0.1 * k)  # noqa: E731
        sweeps = {}
        for k in list(range(BEFORE_GAP + 1)) + list(range(BEFORE_GAP + MISSING, BEFORE_GAP + MISSING + AFTER_GAP)):
            sweeps[k] = u.simulate_sweep(street, drive, k, moving=True)
        truth = {k: drive.matrix((k + 1) * u.SCAN_PERIOD) for k in sweeps}

        diagnostics = Diagnostics()
        replayer = u.Replayer(timeout=10.0)
        self.assertEqual(replayer.wait_ready(), [], "pipeline not wired")
        outputs = {t: u.StampCollector(t, Odometry) for t in ("/laser_odom_to_init", "/aft_mapped_to_init_high_frec",
                                                              "/aft_mapped_to_init")}
        for t, c in outputs.items():
            self.assertTrue(u.wait_connected(c.sub), "no connection on %s" % t)

        answers = {}

        def play(k):
            answers[k] = replayer.wait(replayer.publish(u.cloud_message(sweeps[k], stamp(k))))
            self.assertIsNotNone(answers[k], "sweep %d not answered" % k)

        for k in range(BEFORE_GAP // 2):
            play(k)
        # A duplicate: the next sweep's points under the stamp just answered.
        last = BEFORE_GAP // 2 - 1
        replayer.publish(u.cloud_message(sweeps[last + 1], stamp(last)))
        self.assertEqual(diagnostics.wait_value("scan_registration", DIAG_DUPLICATES, "1"), "1")
        # A late sweep: stamped between two sweeps already answered.
        late = stamp(last) - rospy.Duration(0.05)
        replayer.publish(u.cloud_message(sweeps[last + 1], late))
        self.assertEqual(diagnostics.wait_value("scan_registration", DIAG_LATE, "1"), "1")
        for k in range(BEFORE_GAP // 2, BEFORE_GAP):
            play(k)
        # The gap: sweeps BEFORE_GAP .. BEFORE_GAP + MISSING - 1 never come.
        for k in range(BEFORE_GAP + MISSING, BEFORE_GAP + MISSING + AFTER_GAP):
            play(k)
        self.assertEqual(diagnostics.wait_value("laser_odometry", DIAG_GAPS, "1"), "1")
        time.sleep(1.0)  # let anything that should not come arrive

        # Dropped stamps appear on no output; every sweep sent is answered exactly once on each.
        sent = sorted(stamp(k).to_nsec() for k in answers)
        for topic, collector in outputs.items():
            stamps = collector.stamps()
            self.assertNotIn(late.to_nsec(), stamps, "%s answered the late sweep" % topic)
            self.assertEqual(sorted(stamps), sent, "%s: sweeps answered != sweeps taken" % topic)
            self.assertEqual(len(stamps), len(set(stamps)), "%s answered a stamp twice" % topic)
            for msg in list(collector.by_stamp.values()):
                self.assertTrue(u.pose_is_finite(msg), "%s: non-finite pose" % topic)
        for key, node in ((DIAG_DUPLICATES, "scan_registration"), (DIAG_LATE, "scan_registration")):
            print("%s %s: %s" % (node, key, diagnostics.value(node, key)), flush=True)
        print("laser_odometry %s: %s" % (DIAG_GAPS, diagnostics.value("laser_odometry", DIAG_GAPS)), flush=True)

        # The mapped poses continue the drive across the gap.
        first = min(answers)
        inv_est, inv_true = np.linalg.inv(u.pose_to_matrix(answers[first].pose.pose)), np.linalg.inv(truth[first])
        errors = {}
        for k, a in sorted(answers.items()):
            est = (inv_est @ u.pose_to_matrix(a.pose.pose))[:3, 3]
            true = (inv_true @ truth[k])[:3, 3]
            errors[k] = float(np.linalg.norm(est - true))
        worst = max(errors, key=errors.get)
        before, after = BEFORE_GAP - 1, BEFORE_GAP + MISSING
        step_est = np.linalg.norm(u.pose_to_matrix(answers[after].pose.pose)[:3, 3] -
                                  u.pose_to_matrix(answers[before].pose.pose)[:3, 3])
        step_true = np.linalg.norm(truth[after][:3, 3] - truth[before][:3, 3])
        print("position error: worst %.3f m (sweep %d), after the gap %s; step across the gap %.3f m (true %.3f)"
              % (errors[worst], worst, ", ".join("%.3f" % errors[k] for k in sorted(errors) if k >= after),
                 step_est, step_true), flush=True)
        self.assertLessEqual(errors[worst], MAX_POSITION_ERROR_M)
        self.assertLessEqual(abs(step_est - step_true), MAX_GAP_STEP_ERROR_M)


if __name__ == "__main__":
    rospy.init_node("test_time_handling")
    rostest.rosrun("aloam_nodelet", "time_handling", TestTimeHandling)
