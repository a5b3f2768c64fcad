#!/usr/bin/env python3
"""Loop closure through the real nodelets (sim_loop_playback.test). One draw of the loop_block family (a car
round a city block, about two laps) is played one sweep at a time into aloam.launch with loop_closure:=true.
Asserted: every sweep answered; /diagnostics of laser_mapping reports accepted loops and keyframes; the
trajectory ~save_trajectory writes (corrected by the pose graph) is within its ATE bound, ends within
END_BOUND_M of the truth, and is better than the poses answered live before the loops closed. Then
~save_graph writes the graph, and a second aloam.launch (namespace loop2, graph_file:= that file) must report
the saved keyframes as loaded in /diagnostics, tie its first keyframe to them and answer the drive's first
RESTART_SWEEPS sweeps (a second run from the same start) in the first run's frame, within RESTART_BOUND_M of
the truth.

The bounds are about 1.5x this pipeline's figures on the draw (in the comment; aloam_offline gives the
figures of docs/loop_closure.md on the same sweeps). Update them when the core changes.
"""
import os
import subprocess
import time

import numpy as np
import rospy
import rostest

import aloam_rostest_utils as u
from aloam_nodelet.srv import SaveGraph, SaveTrajectory

FAMILY, SEED, DURATION_S, SEGMENTS = "loop_block", 2, 60.0, "10,20,50"
MAX_ATE_M = 0.09     # corrected trajectory: 0.058 m offline (0.146 m without loop closure)
END_BOUND_M = 0.3    # issue 24's target; offline 0.026 m (0.690 m without)
RESTART_SWEEPS = 40  # the second run over the saved graph
RESTART_BOUND_M = 0.2  # its worst pose against the truth (in the first run's frame); measured: see docs


SECOND_LAUNCH = """<launch>
  <group ns="loop2">
    <include file="$(find aloam_nodelet)/launch/aloam.launch">
      <arg name="sensor" value="VLP16"/>
      <arg name="rviz" value="false"/>
      <arg name="output" value="log"/>
      <arg name="loop_closure" value="true"/>
      <arg name="graph_file" value="%s"/>
    </include>
  </group>
</launch>
"""


class TestSimLoopPlayback(u.ScratchTestCase):

    def tearDown(self):
        u.stop_launch(getattr(self, "launched", None))

    def test_loop_block(self):
        diagnostics = u.DiagnosticsWatcher()
        bag, draw = u.simulate_family(self.scratch, "loop", "VLP16", FAMILY, SEED, DURATION_S)
        answers, truth, elapsed = u.play_simulated(self, bag, ns="loop")
        live, _ = u.evaluate(self, "live", answers, truth, SEGMENTS)
        # The lane may still be verifying the last keyframes: wait until mapping has reported every frame.
        status = diagnostics.wait_frames("loop/laser_mapping", len(answers), timeout=30.0)
        self.assertIsNotNone(status, "no /diagnostics from /loop/laser_mapping")
        rospy.sleep(3.0)  # the lane's last loop work and one more diagnostics period
        values = diagnostics.find("loop/laser_mapping")[2]
        accepted, keyframes = int(values["loops accepted"]), int(values["loop closure keyframes"])
        u.wait_for_service("/loop/laser_mapping/save_trajectory")
        path = self.path("corrected.txt")
        r = rospy.ServiceProxy("/loop/laser_mapping/save_trajectory", SaveTrajectory)(path, "kitti")
        self.assertTrue(r.success, r.message)
        rows = u.read_kitti(path)
        self.assertEqual(len(rows), len(truth), "one corrected pose per sweep")
        gt = self.path("corrected_gt.txt")
        u.write_kitti(gt, truth)
        corrected, _ = u.run_eval(gt, path, segments=SEGMENTS)
        end = float(np.linalg.norm(rows[-1][:3, 3] - u.relative_to_first(truth)[-1][:3, 3]))
        print("RESULT %s seed %d: %d sweeps in %.1f s; %d keyframes, %d loops accepted; ATE live %.3f m, "
              "corrected %.3f m (<= %.3f); end %.3f m (<= %.1f)\n  draw: %s"
              % (FAMILY, SEED, len(answers), elapsed, keyframes, accepted, live["ate_rmse_m"],
                 corrected["ate_rmse_m"], MAX_ATE_M, end, END_BOUND_M, draw), flush=True)
        self.assertGreater(keyframes, 100)
        self.assertGreaterEqual(accepted, 1, "no loop closed")
        self.assertLessEqual(corrected["ate_rmse_m"], MAX_ATE_M)
        self.assertLess(corrected["ate_rmse_m"], live["ate_rmse_m"], "the corrected trajectory is no better")
        self.assertLessEqual(end, END_BOUND_M)
        self.restart_over_saved_graph(diagnostics, bag, keyframes)

    def restart_over_saved_graph(self, diagnostics, bag, keyframes):
        u.wait_for_service("/loop/laser_mapping/save_graph")
        graph = self.path("site.graph")
        r = rospy.ServiceProxy("/loop/laser_mapping/save_graph", SaveGraph)(graph)
        self.assertTrue(r.success, r.message)
        self.assertTrue(os.path.getsize(graph) > 0)
        print("save_graph: %s (%d bytes)" % (r.message, os.path.getsize(graph)), flush=True)
        launch = self.path("second.launch")
        with open(launch, "w") as f:
            f.write(SECOND_LAUNCH % graph)
        # Its own process group, ended by its id at the end (tearDown).
        self.launched = subprocess.Popen(["roslaunch", launch], stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT,
                                         start_new_session=True)
        replayer = u.Replayer(ns="loop2", timeout=20.0)
        self.assertEqual(replayer.wait_ready(timeout=90.0), [], "the second aloam.launch is not wired")
        # The first status of a task is diagnostic_updater's "starting up", without the nodelet's values.
        deadline = time.time() + 30.0
        status = None
        while time.time() < deadline and (status is None or "graph file" not in status[2]):
            status = diagnostics.find("loop2/laser_mapping")
            time.sleep(0.2)
        self.assertTrue(status is not None and "graph file" in status[2], "no /diagnostics from /loop2/laser_mapping")
        values = status[2]
        self.assertTrue(values["graph file"].startswith("loaded"), values["graph file"])
        # The graph saved after the last diagnostics of the first run may hold a few more keyframes.
        self.assertGreaterEqual(int(values["loop closure keyframes loaded"]), keyframes)
        clouds = u.read_bag_clouds(bag)[:RESTART_SWEEPS]
        truth = u.bag_ground_truth(bag)[:RESTART_SWEEPS]
        answers = replayer.play(clouds, log_every=10)
        self.assertEqual([i for i, a in enumerate(answers) if a is None], [], "second run: sweeps unanswered")
        # In the first run's frame: the identity at the common start, as the truth relative to its first pose.
        errors, _ = u.position_errors(u.answered_matrices(answers), truth)
        status = diagnostics.wait_frames("loop2/laser_mapping", RESTART_SWEEPS, timeout=30.0)
        self.assertIsNotNone(status)
        rospy.sleep(3.0)  # the lane's loop work on the last keyframes, and one more diagnostics period
        values = diagnostics.find("loop2/laser_mapping")[2]
        print("RESULT second run over the saved graph: %s keyframes loaded, tie: %s, %s loops accepted; worst pose "
              "of %d sweeps %.3f m off the truth (<= %.2f)"
              % (values["loop closure keyframes loaded"], values["tie to the loaded graph"], values["loops accepted"],
                 RESTART_SWEEPS, errors.max(), RESTART_BOUND_M), flush=True)
        self.assertTrue(values["tie to the loaded graph"].startswith("tied"), values["tie to the loaded graph"])
        self.assertLessEqual(errors.max(), RESTART_BOUND_M)


if __name__ == "__main__":
    rospy.init_node("test_sim_loop_playback")
    rostest.rosrun("aloam_nodelet", "sim_loop_playback", TestSimLoopPlayback)
