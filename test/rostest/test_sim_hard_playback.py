#!/usr/bin/env python3
"""Hard cases of issue 11 through the real nodelets (sim_hard_playback.test), each a seeded aloam_sim
sequence played one sweep at a time into its own aloam.launch pipeline:

- office_vlp16: the L-shaped office corridor (2.5 m wide, a 90 deg left turn) walked hand-held with a VLP-16.
  The motion along the corridor is weakly constrained in many sweeps. Asserted: ATE within its bound, no
  estimated step moves against the true step (among the true steps longer than 5 cm), and the degeneracy
  is reported in /diagnostics: frames remapped (partially degenerate) or degraded are counted, and the
  "degenerate (sensor frame)" string names at least one direction at some point of the walk.
- office_os0: the same walk with an Ouster OS0-64 (+-45 deg): ATE bound, no backward step.
- handheld_5hz: the urban hand-held walk (90 deg/s yaw bursts) behind a throttle, every 2nd sweep of the
  10 Hz sensor (aloam_sim --keep-every 2, stamps 0.2 s apart): ATE and rotation drift bounds, and odometry's
  /diagnostics count the frames where motion hypotheses were tried and where another start was kept.
Each case also has a rotation drift bound; the directions named in the office's /diagnostics must be unit
vectors in the sensor frame ("translation along (x, y, z)" / "rotation about (x, y, z)").

The figures of the same cases over seeds 1-3 offline, new handling against --baseline, are checked by
test/tools/check_hard_cases.sh.
"""
import re

import numpy as np
import rospy
import rostest

import aloam_rostest_utils as u

DEGENERATE_KEY = "degenerate (sensor frame)"
REMAPPED_KEY = "remapped frames (partially degenerate)"
DEGRADED_KEY = "degraded frames"
HYPOTHESES_TRIED_KEY = "hypotheses tried (frames)"
HYPOTHESES_KEPT_KEY = "hypotheses kept (frames, another start won)"

# Bounds about 1.5x the figure measured through the pipeline (in the comment; aloam_offline agrees to the
# digit, and test/tools/check_hard_cases.sh has seeds 1-3), update when the core changes. Seeds vary by case;
# the 5 Hz walk uses seed 2, its hardest (seeds 1/3: ATE 0.129/0.100 m).
#   ns: (sensor, scene, trajectory, duration s, keep_every, seed, segments, max ATE m, max rot deg/100 m)
CASES = {
    "office_vlp16": ("VLP16", "office", "handheld_turn", 18.0, 1, 1, "5,10,20", 0.036, 11.0),  # 0.024 m, 7.0 (0.094, 155.9 with fixed leaves)
    "office_os0": ("OS0_64", "office", "handheld_turn", 18.0, 1, 2, "5,10,20", 0.025, 9.0),    # 0.015 m, 5.8 (0.110, 10.2 with fixed leaves)
    "handheld_5hz": ("VLP16", "urban", "handheld", 18.0, 2, 2, "5,10,20", 0.15, 65.0),         # 0.077 m (0.546 before the motion hypotheses), 43.2
}
# A direction as aloam::describe writes it: "translation along (x, y, z)" or "rotation about (x, y, z)",
# a unit vector in the sensor frame, optionally followed by " with <the other part>".
DIRECTION = re.compile(r"(translation along|rotation about) \(([-0-9.]+), ([-0-9.]+), ([-0-9.]+)\)")


class TestSimHardPlayback(u.ScratchTestCase):

    def play_case(self, ns):
        sensor, scene, trajectory, duration, keep, seed, segments, max_ate, max_rot = CASES[ns]
        bag = u.simulate(self.scratch, ns, sensor, scene, trajectory, duration, seed, keep_every=keep)
        answers, truth, elapsed = u.play_simulated(self, bag, ns=ns)
        metrics, report = u.evaluate(self, ns, answers, truth, segments)
        backward, steps = u.backward_steps(u.answered_matrices(answers), truth)
        print("RESULT %s (%s, %s %s, keep every %d, seed %d): %d sweeps in %.1f s over %.1f m; ATE %.3f m (<= %.2f), "
              "rotation %.1f deg/100 m (<= %s), drift %.2f %%, backward steps %d of %d"
              % (ns, sensor, scene, trajectory, keep, seed, len(answers), elapsed, u.path_length(truth),
                 metrics["ate_rmse_m"], max_ate, metrics["rotation_deg_per_100m"], max_rot,
                 metrics["translation_drift_percent"], backward, steps), flush=True)
        self.assertLessEqual(metrics["ate_rmse_m"], max_ate, "%s ATE" % ns)
        if max_rot is not None:
            self.assertLessEqual(metrics["rotation_deg_per_100m"], max_rot, "%s rotation drift" % ns)
        return answers, backward, steps

    def test_office_vlp16(self):
        ns = "office_vlp16"
        diagnostics = u.DiagnosticsWatcher(history_keys=(DEGENERATE_KEY,))
        answers, backward, steps = self.play_case(ns)
        counts = {}
        for name in ("laser_odometry", "laser_mapping"):
            status = diagnostics.wait_frames("/%s/%s" % (ns, name), len(answers))
            self.assertIsNotNone(status, "no /diagnostics from %s/%s covering all frames" % (ns, name))
            counts[name] = (int(status[2][REMAPPED_KEY]), int(status[2][DEGRADED_KEY]))
        seen = [v for name in ("laser_odometry", "laser_mapping")
                for v in diagnostics.values_seen("/%s/%s" % (ns, name), DEGENERATE_KEY)]
        named = sorted(set(v for v in seen if v != "none"))
        diagnostics.sub.unregister()
        print("RESULT %s diagnostics: remapped/degraded frames: odometry %d/%d, mapping %d/%d; %d of %d "
              "samples name degenerate directions, e.g. %s"
              % (ns, counts["laser_odometry"][0], counts["laser_odometry"][1], counts["laser_mapping"][0],
                 counts["laser_mapping"][1], len([v for v in seen if v != "none"]), len(seen), named[:3]),
              flush=True)
        self.assertEqual(backward, 0, "%d of %d estimated steps against the true step" % (backward, steps))
        self.assertGreater(sum(sum(c) for c in counts.values()), 0, "degeneracy not reported in /diagnostics")
        self.assertTrue(named, "no /diagnostics sample named a degenerate direction (%d samples)" % len(seen))
        for text in named:
            for direction in text.split("; "):
                m = DIRECTION.match(direction)
                self.assertIsNotNone(m, "not a direction in the sensor frame: %r" % direction)
                norm = np.linalg.norm([float(m.group(i)) for i in (2, 3, 4)])
                self.assertAlmostEqual(norm, 1.0, delta=0.02, msg="not a unit vector: %r" % direction)

    def test_office_os0(self):
        answers, backward, steps = self.play_case("office_os0")
        self.assertEqual(backward, 0, "%d of %d estimated steps against the true step" % (backward, steps))

    def test_urban_handheld_5hz(self):
        ns = "handheld_5hz"
        diagnostics = u.DiagnosticsWatcher()
        answers, _, _ = self.play_case(ns)
        status = diagnostics.wait_frames("/%s/laser_odometry" % ns, len(answers))
        diagnostics.sub.unregister()
        self.assertIsNotNone(status, "no /diagnostics from %s/laser_odometry covering all frames" % ns)
        tried, kept = int(status[2][HYPOTHESES_TRIED_KEY]), int(status[2][HYPOTHESES_KEPT_KEY])
        print("RESULT %s diagnostics: motion hypotheses tried on %d frames, another start kept on %d"
              % (ns, tried, kept), flush=True)
        # The yaw bursts at 5 Hz defeat the constant-velocity guess (offline: hypotheses tried on some frames).
        self.assertGreater(tried, 0, "no frame tried motion hypotheses")
        self.assertLessEqual(kept, tried)


if __name__ == "__main__":
    rospy.init_node("test_sim_hard_playback")
    rostest.rosrun("aloam_nodelet", "sim_hard_playback", TestSimHardPlayback)
