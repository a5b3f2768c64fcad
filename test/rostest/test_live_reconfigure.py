#!/usr/bin/env python3
"""dynamic_reconfigure of laser_mapping in the middle of a replay (live_reconfigure.test).

The 40-sweep make_test_bag drive is replayed sweep by sweep through aloam.launch (VLP16). Before sweep 20
the mapping is reconfigured to {cube_size: 25, corner_leaf_size: 0.3, surf_leaf_size: 0.6,
max_iterations: 6} with dynamic_reconfigure's client:
- the client returns the new configuration; the server publishes it (parameter_updates, read with
  get_configuration) and the parameter server holds it
- the map keeps its points across the change (~save_map before and after: same PCD point count; the
  cube size change re-buckets the map)
- every sweep is still answered, before and after
- the poses stay continuous: around the change (sweeps 15..25) no step between consecutive answers
  differs from the true step by more than 0.5 m (the drive moves 1 m per sweep), and the whole
  trajectory stays within the playback bounds (drift, ATE against the ground truth)
- the map goes on growing after the change (a third ~save_map at the end has more points)
Before sweep 30 `rosrun dynamic_reconfigure dynparam set /laser_mapping "{cube_size: 50.0, max_iterations: 4}"`
(the README's command) changes those two back, the rest stays, and again no map point is lost.
"""
import subprocess
import time

import numpy as np
import rospy
import rostest
from dynamic_reconfigure.client import Client

from aloam_nodelet.srv import SaveMap

import aloam_rostest_utils as u

CHANGE_AT = 20
NEW_CONFIG = {"cube_size": 25.0, "corner_leaf_size": 0.3, "surf_leaf_size": 0.6, "max_iterations": 6}
# and back with the command line the README documents, later in the same replay
CLI_AT = 30
CLI_CONFIG = "{cube_size: 50.0, max_iterations: 4}"
MAX_JUMP_M = 0.5
MAX_DRIFT_PERCENT = 1.0
MAX_ATE_M = 0.06


def published_config(client, key, value, timeout=5.0):
    """The configuration the server publishes on parameter_updates (the client caches the latest), once
    it shows key == value or after `timeout`."""
    deadline = time.time() + timeout
    config = client.get_configuration(timeout=timeout)
    while abs(config[key] - value) > 1e-9 and time.time() < deadline:
        time.sleep(0.05)
        config = client.get_configuration(timeout=timeout)
    return config


class TestLiveReconfigure(u.ScratchTestCase):

    def save_map(self, name):
        response = self.save(self.path(name))
        self.assertTrue(response.success, response.message)
        return u.pcd_points(self.path(name))[0]

    def test_reconfigure_mapping_during_replay(self):
        bag, gt = u.make_test_bag(self.scratch, sweeps=40, sensor="VLP16")
        clouds = u.read_bag_clouds(bag)
        replayer = u.Replayer(ns="", timeout=10.0)
        self.assertEqual(replayer.wait_ready(), [], "pipeline not wired")
        self.assertTrue(u.wait_for_service("/laser_mapping/save_map", 20))
        self.save = rospy.ServiceProxy("/laser_mapping/save_map", SaveMap)
        client = Client("/laser_mapping", timeout=20)
        initial = client.get_configuration(timeout=10)
        self.assertAlmostEqual(initial["cube_size"], 50.0, msg="config/VLP16.yaml's cube_size at start-up")
        record = {}

        def before_frame(i, answers):
            if i == CLI_AT:
                record["cli_before"] = self.save_map("cli_before.pcd")
                command = ["rosrun", "dynamic_reconfigure", "dynparam", "set", "/laser_mapping", CLI_CONFIG]
                proc = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                      universal_newlines=True, timeout=60)
                record["cli"] = proc
                record["cli_after"] = self.save_map("cli_after.pcd")
                record["cli_read_back"] = published_config(client, "cube_size", 50.0)
            if i != CHANGE_AT:
                return
            record["before"] = self.save_map("before.pcd")
            t0 = time.time()
            record["returned"] = client.update_configuration(NEW_CONFIG)
            record["seconds"] = time.time() - t0
            record["after"] = self.save_map("after.pcd")
            record["read_back"] = published_config(client, "cube_size", NEW_CONFIG["cube_size"])
            record["params"] = {key: rospy.get_param("/laser_mapping/" + key) for key in NEW_CONFIG}

        answers = replayer.play(clouds, before_frame=before_frame)
        self.assertIn("returned", record, "the replay never reached sweep %d" % CHANGE_AT)
        print("reconfigure took %.3f s; map %d points before, %d after" % (record["seconds"], record["before"],
                                                                       record["after"]), flush=True)
        for key, value in NEW_CONFIG.items():
            self.assertAlmostEqual(record["returned"][key], value, msg="update_configuration returned %s" % key)
            self.assertAlmostEqual(record["read_back"][key], value, msg="get_configuration %s" % key)
            self.assertAlmostEqual(record["params"][key], value, msg="parameter server: %s" % key)
        for key in ("outer_iterations", "plane_neighbours", "eviction_radius"):
            self.assertAlmostEqual(record["returned"][key], initial[key], msg="%s unchanged" % key)
        self.assertGreater(record["before"], 1000)
        self.assertEqual(record["after"], record["before"], "the map lost or gained points on reconfiguring")

        self.assertIn("cli", record, "the replay never reached sweep %d" % CLI_AT)
        self.assertEqual(record["cli"].returncode, 0, "dynparam set failed: %s" % record["cli"].stdout)
        self.assertAlmostEqual(record["cli_read_back"]["cube_size"], 50.0)
        self.assertEqual(record["cli_read_back"]["max_iterations"], 4)
        self.assertAlmostEqual(record["cli_read_back"]["surf_leaf_size"], 0.6,
                               msg="dynparam set changed only what it names")
        print("dynparam set at sweep %d: map %d points before, %d after" % (CLI_AT, record["cli_before"],
                                                                          record["cli_after"]), flush=True)
        self.assertEqual(record["cli_after"], record["cli_before"], "the map lost or gained points on reconfiguring")

        unanswered = [i for i, a in enumerate(answers) if a is None]
        self.assertEqual(unanswered, [], "sweeps without aft_mapped_to_init")
        final = self.save_map("final.pcd")
        self.assertGreater(final, record["after"], "the map grows after the change")

        est = u.answered_matrices(answers)
        truth = u.read_kitti(gt)
        est = [np.linalg.inv(est[0]) @ m for m in est]
        jumps = []
        for i in range(1, len(est)):
            step = est[i][:3, 3] - est[i - 1][:3, 3]
            true_step = truth[i][:3, 3] - truth[i - 1][:3, 3]
            jumps.append(np.linalg.norm(step - true_step))
        around = jumps[CHANGE_AT - 6:CHANGE_AT + 5]  # steps 15->16 .. 25->26
        print("step error around the change: max %.3f m (whole drive: max %.3f m)" % (max(around), max(jumps)),
              flush=True)
        self.assertLess(max(around), MAX_JUMP_M, "pose jump at the reconfiguration")
        self.assertLess(max(jumps), MAX_JUMP_M)

        trajectory = self.path("trajectory.txt")
        u.write_kitti(trajectory, u.answered_matrices(answers))
        metrics, report = u.run_eval(gt, trajectory, segments="5,10,20")
        print(report, flush=True)
        print("with the change at sweep %d: drift %.3f %% (<= %.1f), ATE %.3f m (<= %.2f)"
              % (CHANGE_AT, metrics["translation_drift_percent"], MAX_DRIFT_PERCENT, metrics["ate_rmse_m"],
                 MAX_ATE_M), flush=True)
        self.assertLessEqual(metrics["translation_drift_percent"], MAX_DRIFT_PERCENT)
        self.assertLessEqual(metrics["ate_rmse_m"], MAX_ATE_M)


if __name__ == "__main__":
    rospy.init_node("test_live_reconfigure")
    rostest.rosrun("aloam_nodelet", "live_reconfigure", TestLiveReconfigure)
