#!/usr/bin/env python3
"""The degenerate scenes (sim_degenerate_playback.test): a 2.5 m wide corridor (walls, floor and ceiling
leave the motion along it to a door or light every few metres) and an open field (flat ground, a few
objects 8 m or more away), each a seeded 4 s straight line at 5 m/s with a VLP-16, played one sweep at a
time into its own pipeline.

With the all-or-nothing fallback (81f6493) LOAM could not track these (the motion along the corridor and
across the field is unobservable in most sweeps). With degeneracy handled per direction (issue 11) the
solve is kept along the well-constrained directions and the prediction only along the weak ones, so the
corridor is now tracked; the field still drifts. What must hold:
- every sweep is answered and no pose is NaN or Inf,
- the degeneracy is reported: odometry or mapping counts frames in /diagnostics that were remapped
  (solved along the well-constrained directions only, the prediction kept along the weak ones) or
  degraded (no usable solve, the whole prediction kept),
- the divergence stays within a stated bound: position error against the ground truth (both relative to
  the first sweep) and heading error at most the bounds below.
"""
import numpy as np
import rospy
import rostest

import aloam_rostest_utils as u

DURATION_S = 4.0
SEED = 3
# Measured through the pipeline with per-direction remapping (issue 11, seed 3): the corridor
# estimate ends 1.57 m off after 19.5 m (1.28 m before mapping searched hard frames longer, 9.43 m with the
# old fallback), heading error at most 11.1 deg; the field ends 14.21 m off (16.21 m before; 30.2 m while
# any motion hypothesis with more inliers replaced the prediction, which hypothesis_min_gain stopped),
# heading error at most 42.1 deg. Degraded frames are now 0
# in both, remapped frames 34 (odometry) / 38 (mapping) in the corridor, 21 / 38 in the field.
# Since mapping's leaves shrink in confined spaces (a quarter in this corridor) the corridor ends 0.35 m
# off (at most 0.36 m), heading error at most 0.6 deg, remapped frames 6 (odometry) / 0 (mapping); the
# field (leaves unchanged there) measured 17.66 m, 46.9 deg.
# Bounds about 1.5-2x:   max position error (m)   max heading error (deg)
BOUNDS = {
    "corridor": (0.7, 3.0),
    "field": (21.0, 63.0),
}


class TestSimDegeneratePlayback(u.ScratchTestCase):

    def check_scene(self, scene):
        max_position, max_heading = BOUNDS[scene]
        diagnostics = u.DiagnosticsWatcher()
        bag = u.simulate(self.scratch, scene, "VLP16", scene, "straight", DURATION_S, SEED)
        answers, truth, elapsed = u.play_simulated(self, bag, ns=scene)
        positions, headings = u.position_errors(u.answered_matrices(answers), truth)
        degraded, remapped = {}, {}
        for name in ("laser_odometry", "laser_mapping"):
            status = diagnostics.wait_frames("/%s/%s" % (scene, name), len(answers))
            self.assertIsNotNone(status, "no /diagnostics from %s/%s covering all frames" % (scene, name))
            degraded[name] = int(status[2]["degraded frames"])
            remapped[name] = int(status[2]["remapped frames (partially degenerate)"])
        diagnostics.sub.unregister()
        travelled = u.path_length(truth)
        print("RESULT %s: %d sweeps in %.1f s over %.1f m; position error max %.2f m, end %.2f m (<= %.1f); "
              "heading error max %.1f deg (<= %.0f); degraded frames: odometry %d, mapping %d; remapped frames: "
              "odometry %d, mapping %d"
              % (scene, len(answers), elapsed, travelled, positions.max(), positions[-1], max_position,
                 headings.max(), max_heading, degraded["laser_odometry"], degraded["laser_mapping"],
                 remapped["laser_odometry"], remapped["laser_mapping"]), flush=True)
        self.assertTrue(np.all(np.isfinite(positions)))
        self.assertGreater(sum(degraded.values()) + sum(remapped.values()), 0,
                           "degeneracy not reported in /diagnostics (neither remapped nor degraded frames)")
        self.assertLessEqual(positions.max(), max_position)
        self.assertLessEqual(headings.max(), max_heading)

    def test_corridor(self):
        self.check_scene("corridor")

    def test_field(self):
        self.check_scene("field")


if __name__ == "__main__":
    rospy.init_node("test_sim_degenerate_playback")
    rostest.rosrun("aloam_nodelet", "sim_degenerate_playback", TestSimDegeneratePlayback)
