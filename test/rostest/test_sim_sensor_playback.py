#!/usr/bin/env python3
"""One sensor preset on the simulated urban drive, through the real pipeline (sim_sensor_playback.test).

aloam_sim writes a seeded 8 s urban car drive (10 m/s, a weave, over a hill; 80 sweeps, driver-like fields:
Velodyne ring/time, Ouster organized with t in ns and top-down rings) for the preset; its clouds are played
into aloam.launch sensor:=PRESET one at a time, each waiting for its aft_mapped_to_init. Every sweep must be
answered with a finite pose, and aloam_eval against the bag's ground truth (10, 20, 40 m segments) must stay
within the preset's drift and ATE bounds. The nodelets' mean milliseconds per frame from /diagnostics are
printed (not asserted: the machine is shared).
"""
import rospy
import rostest

import aloam_rostest_utils as u

DURATION_S = 8.0
SEED = 1
SEGMENTS = "10,20,40"
# Bounds set from the pipeline's own measurement on this sequence with about 2x margin on drift and
# 1.8x on ATE; the measured values (this test, 80 sweeps) beside each.
#          drift %  ATE m      measured: drift %, ATE m
BOUNDS = {
    "VLP16": (0.70, 0.09),   # 0.351, 0.048
    "HDL32": (0.65, 0.13),   # 0.312, 0.069
    "HDL64": (0.75, 0.14),   # 0.367, 0.072
    "VLP32C": (0.65, 0.13),  # 0.313, 0.071
    "OS1_64": (0.65, 0.14),  # 0.328, 0.076
    "OS0_64": (0.70, 0.15),  # 0.355, 0.080
}
NODELETS = ("scan_registration", "laser_odometry", "laser_mapping")


class TestSimSensorPlayback(u.ScratchTestCase):

    def test_urban_drive(self):
        sensor = rospy.get_param("~sensor")
        self.assertIn(sensor, BOUNDS)
        max_drift, max_ate = BOUNDS[sensor]
        diagnostics = u.DiagnosticsWatcher()
        bag = u.simulate(self.scratch, "urban_" + sensor, sensor, "urban", "car", DURATION_S, SEED)
        answers, truth, elapsed = u.play_simulated(self, bag)
        metrics, report = u.evaluate(self, "urban_" + sensor, answers, truth, SEGMENTS)
        print(report, flush=True)
        timing = []
        for name in NODELETS:
            status = diagnostics.wait_frames(name, len(answers))
            self.assertIsNotNone(status, "no /diagnostics from %s covering all %d frames" % (name, len(answers)))
            timing.append("%s %s ms" % (name, status[2].get("mean frame (ms)")))
        drift, ate = metrics["translation_drift_percent"], metrics["ate_rmse_m"]
        print("RESULT %s urban car: %d sweeps in %.1f s; drift %.3f %% (<= %.2f), ATE %.3f m (<= %.2f); mean per "
              "frame: %s" % (sensor, len(answers), elapsed, drift, max_drift, ate, max_ate, ", ".join(timing)),
              flush=True)
        self.assertLessEqual(drift, max_drift)
        self.assertLessEqual(ate, max_ate)


if __name__ == "__main__":
    rospy.init_node("test_sim_sensor_playback")
    rostest.rosrun("aloam_nodelet", "sim_sensor_playback", TestSimSensorPlayback)
