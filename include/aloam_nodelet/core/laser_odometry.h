// LOAM laser odometry: scan-to-scan edge and plane matching against the previous sweep.
#pragma once

#include <algorithm>
#include <memory>

#include <vector>

#include "aloam_nodelet/core/executor.h"
#include "aloam_nodelet/core/feature_set.h"
#include "aloam_nodelet/core/kd_tree.h"
#include "aloam_nodelet/core/pose.h"
#include "aloam_nodelet/core/pose_solver.h"

namespace aloam
{
struct LaserOdometryConfig
{
  int max_iterations = 4;               ///< Levenberg-Marquardt iterations per solve
  int outer_iterations = 2;             ///< correspondence searches per sweep, each followed by a solve
  double distance_sq_threshold = 25.0;  ///< nearest neighbour farther than this (m^2) is no match
  double nearby_scan = 2.5;             ///< rings searched on each side for the second/third point
  /// The neighbourhood on neighbouring rings as an elevation window: the second point of a line and the
  /// second and third of a plane come from the rings within nearby_elevation_deg of the nearest point's
  /// ring (see ringReach), resolved through ring_elevations_deg, so the reach in degrees is the same on a
  /// VLP-32C's 0.33 deg central beams, an OS0's 1.4 deg and a VLP-16's 2 deg (ring counting reaches 0.7 to
  /// 4 deg). 0.8 deg resolves to the two rings of nearby_scan on each side of every HDL-64 ring and to one
  /// ring on sensors with beams 1.3 deg or more apart. Off (0) by default: against two rings it measured
  /// better only by noise-sized margins on some sensors (HDL-32, OS0-64, VLP-32C on the simulated urban car)
  /// and worse on others (VLP-16 hand-held, OS1-64 rotation drift); config/*.yaml switch it on where it
  /// measured better or equal. <= 0, or no beam table, or a ring beyond the table: nearby_scan rings (A-LOAM).
  double nearby_elevation_deg = 0.0;
  /// The sensor's beam elevations in degrees, ascending, index = ring (SensorModel::elevationsDeg()).
  /// Pipeline fills it from the registration's sensor model when it is empty.
  std::vector<double> ring_elevations_deg;
  /// Correct motion within the sweep (needs per-point time, from the point field or the azimuth): each
  /// point is moved by the velocity times its time in the sweep. Sources that deliver keyframes or clouds
  /// already deskewed (or with no meaningful intra-sweep time) set this false: the clouds are then taken
  /// as rigid snapshots at their stamps, and the motion prediction still scales with the time between
  /// stamps (time_scaling), so any input rate works.
  bool deskew = false;
  bool constant_velocity = true;  ///< start each solve from the previous sweep's velocity
  /// The motion model is a velocity: the prediction for a sweep is the last motion scaled by (time since
  /// the last stamp) / (time the last motion took), and deskewing uses velocity x scan_period, so both are
  /// right at any input rate (throttled topics, dropped sweeps). false: the last stamp-to-stamp motion is
  /// the prediction and the deskew motion whatever the spacing (A-LOAM; right only when sweeps are
  /// scan_period apart). At a steady rate equal to scan_period both give the same result.
  bool time_scaling = true;
  double huber_delta = 0.1;  ///< robust loss scale (m)
  /// Fewer matches: keep the motion prior, report degraded. A sweep of one ring gives about 30, which can
  /// hold five directions and push the sixth far off; a real sweep gives hundreds.
  int min_correspondences = 50;
  int min_last_corners = 10;                ///< previous sweep needs this many edge points to match against
  int min_last_surfs = 100;                 ///< ... and this many plane points
  double max_translation_per_sweep = 10.0;  ///< a larger solved motion is rejected as divergent (m)
  /// Degeneracy: a direction constrained less than this (PoseProblem::constraintStrength, rotations as the
  /// motion of a point constraint_lever_arm metres away) is weak (see degeneracy_remap and soft_remap).
  double min_constraint = 10.0;
  double constraint_lever_arm = 10.0;
  /// Degeneracy per direction (solution remapping): directions of the motion whose constraint (eigenvalue,
  /// scaled as above) is below min_constraint keep the prediction, the others take the solve; only a frame
  /// with no constrained direction keeps the whole prediction. false: any weak direction keeps the whole
  /// prediction (all six degrees of freedom; A-LOAM-like all-or-nothing).
  bool degeneracy_remap = true;
  /// With degeneracy_remap: a weak direction keeps the share eigenvalue / min_constraint of the solve's step
  /// instead of none (PoseProblem::remap). A direction just under the threshold is mostly solved, one with
  /// no constraint keeps the prediction. false: the prediction along every weak direction.
  bool soft_remap = true;
  /// More degenerate directions than this: the whole prediction is kept (see MatchSolveOptions::max_degenerate).
  int max_degenerate_directions = 3;
  /// A point is an inlier when its match lies within this (m) of the solved motion; the share of inliers
  /// among all sharp and flat points says whether the solve found the motion.
  double inlier_residual = 0.1;
  /// Robust to a wrong constant-velocity guess (a yaw burst, a stop, a throttled start from rest): when the
  /// solve from the prediction leaves fewer than hypothesis_min_inlier_share of the points inliers, the
  /// motion is also solved from other starts (the prediction with a wider first search, zero motion, the
  /// prediction doubled, the prediction turned by +-hypothesis_yaw_deg and twice that about the sensor's
  /// z axis; from a zero prediction, translations of +-hypothesis_translation and twice that along the
  /// sensor's x and y axes instead of zero and doubled), each with hypothesis_outer_iterations searches,
  /// and the start whose solve keeps the most inliers wins. false: one solve from the prediction (A-LOAM).
  bool motion_hypotheses = true;
  double hypothesis_min_inlier_share = 0.5;
  /// Another start replaces the prediction's solve only with an inlier share this much higher.
  double hypothesis_min_gain = 0.1;
  double hypothesis_yaw_deg = 20.0;
  double hypothesis_translation = 2.5;  ///< m; <= 0: no translation starts
  int hypothesis_outer_iterations = 4;
  /// Factor on distance_sq_threshold for the first search of every hypothesis.
  double hypothesis_search_scale = 4.0;
  int threads = 2;  ///< threads sharing the correspondence search (results do not depend on it)
};

/// Rings searched below and above a ring for the points that complete a match.
struct RingReach
{
  int below = 0;
  int above = 0;
};

/// For every ring of the beam table `elevations_deg` (ascending, degrees; index = ring), the rings below
/// and above it within `window_deg`: a neighbouring ring counts when the boundary of its elevation cell
/// nearest to the ring (the midpoint between it and the next ring inwards) lies within the window, so the
/// window covers the cells of the rings it reaches. At least one ring on each side that has one.
std::vector<RingReach> ringReach(const std::vector<double>& elevations_deg, double window_deg);

enum class OdometryStatus
{
  kInitialized,  ///< first sweep: pose is identity, nothing to match yet
  kOk,
  kDegraded,  ///< too few or degenerate correspondences, or a divergent solve: the motion prior was used
  kRemapped,  ///< some directions degenerate: the prior kept along them, the solve along the others
};

/// One sweep's odometry: the pose and the clouds mapping needs, in the sensor frame at the sweep end.
struct OdometryFrame
{
  double stamp = 0.0;
  Pose pose;    ///< odometry world <- sensor at the sweep end
  Pose motion;  ///< previous sweep end <- this sweep end
  OdometryStatus status = OdometryStatus::kInitialized;
  int corner_matches = 0;
  int plane_matches = 0;
  double constraint = 0.0;  ///< how well the matches pin the motion down (0: degenerate)
  /// Directions the matches did not pin down (eigenvalue below min_constraint), in the sensor frame at the
  /// sweep end; their number is the count of degenerate directions (6: nothing constrained).
  std::vector<DegenerateDirection> degenerate;
  double dt = 0.0;            ///< seconds since the previous sweep's stamp (0 for the first)
  double scan_period = 0.1;   ///< the sweep's nominal duration (s)
  double inlier_share = 0.0;  ///< share of the sharp and flat points that are inliers of the solved motion
  /// The solve from the prediction looked wrong (few inliers) and other starts were tried
  /// (LaserOdometryConfig::motion_hypotheses); `hypothesis` is the one kept (0: the prediction).
  bool hypotheses_tried = false;
  int hypothesis = 0;
  /// The clouds still carry motion distortion that deskewing was asked to remove: the first sweep,
  /// whose motion is unknown. Mapping does not build its map from such clouds.
  bool distorted = false;
  /// Odometry had trouble with the sweep: other starts tried, degraded or remapped.
  bool hard() const
  {
    return hypotheses_tried || status == OdometryStatus::kDegraded || status == OdometryStatus::kRemapped;
  }
  std::shared_ptr<const Cloud> corners;  ///< less sharp points
  std::shared_ptr<const Cloud> surfs;    ///< less flat points
  /// Every point of the sweep, for display only: no stage computes with it. Its points are as registration
  /// gave them (shared, no copy) and still to be moved by `full_motion`; fullAtSweepEnd() does that for
  /// whoever displays them (deskewing it for every sweep was a measurable share of odometry's pose path:
  /// docs/performance.md).
  std::shared_ptr<const Cloud> full;
  Pose full_motion;  ///< sweep start <- sweep end, as deskewToSweepEnd takes it; identity: `full` is done
};

class LaserOdometry
{
public:
  /// Parallel regions run on `executor` (a pipeline shares one among its stages); without one the stage
  /// makes its own, sized from the configuration's `threads`.
  explicit LaserOdometry(LaserOdometryConfig config = {}, std::shared_ptr<Executor> executor = nullptr);

  const LaserOdometryConfig& config() const { return config_; }
  const std::shared_ptr<Executor>& executor() const { return executor_; }
  void setConfig(const LaserOdometryConfig& config);
  /// Rings searched on each side of `ring` (from nearby_elevation_deg, or nearby_scan).
  RingReach reach(int ring) const;

  /// Matches `features` against the previous sweep and returns the new pose. The frame shares the
  /// clouds of `features` when no deskewing is done (no copy). track() then indexLast().
  OdometryFrame process(const std::shared_ptr<const FeatureSet>& features);

  /// The new pose and frame; the sweep becomes the reference for the next one, indexed by indexLast().
  OdometryFrame track(const std::shared_ptr<const FeatureSet>& features);
  /// Builds the search trees over the last tracked sweep (off the latency path: a node publishes the
  /// frame first). track() does it itself if it was not done.
  void indexLast();

  /// Forgets the previous sweep and the pose; the next sweep starts a new trajectory at identity.
  void reset();
  /// Forgets the motion prior (after a gap in the data): the next sweep is solved from an identity prior and
  /// not deskewed, since the motion across the gap is no per-sweep velocity; nor is it the prior of the sweep
  /// after. The pose and the previous sweep are kept.
  void resetMotionPrior()
  {
    motion_ = Pose();
    motion_unknown_ = true;
  }
  bool initialized() const { return last_corners_ != nullptr; }
  /// The motion prior (previous sweep end <- sweep end) a sweep stamped `stamp` would start from.
  Pose prediction(double stamp) const { return predict(initialized() ? std::max(stamp - last_stamp_, 0.0) : 0.0); }
  const Pose& pose() const { return pose_; }

private:
  struct Matches
  {
    int corners = 0;
    int planes = 0;
    double constraint = 0.0;
    std::vector<DegenerateDirection> degenerate;
    bool remapped = false;
    double inlier_share = 0.0;
  };

  LaserOdometryConfig config_;
  std::shared_ptr<Executor> executor_;
  std::vector<RingReach> ring_reach_;  // per ring of config_.ring_elevations_deg; empty: nearby_scan
  Pose pose_;                          // world <- current sweep end
  Pose motion_;                        // last sweep end <- current sweep end (the constant-velocity prior)
  std::shared_ptr<const Cloud> last_corners_;
  std::shared_ptr<const Cloud> last_surfs_;
  bool last_distorted_ = false;  // the previous sweep's clouds could not be deskewed
  bool last_indexed_ = false;    // the trees below index last_corners_ / last_surfs_
  bool motion_unknown_ = false;  // resetMotionPrior() was called: no velocity for the next sweep
  double motion_dt_ = 0.0;       // seconds motion_ took (0: unknown)
  double last_stamp_ = 0.0;      // stamp of the previous sweep
  // The previous sweep's features indexed as a whole (nearest point) and ring by ring (the points
  // that complete a line or a plane on neighbouring rings).
  KdTree corner_tree_;
  KdTree surf_tree_;
  std::vector<KdTree> corner_ring_trees_;
  std::vector<KdTree> surf_ring_trees_;

  /// One solve from `motion` with `outer_iterations` searches, the first `search_scale` times as wide.
  Matches solve(const Cloud& sharp, const Cloud& flat, Pose& motion, int outer_iterations, double search_scale) const;
  /// The starts tried after a poor solve from `prior` (see LaserOdometryConfig::motion_hypotheses).
  std::vector<Pose> hypotheses(const Pose& prior) const;
  bool matchEdge(const Point& p, const Pose& motion, double search_scale, LineMatch& match) const;
  bool matchPlane(const Point& p, const Pose& motion, double search_scale, PlaneMatch& match) const;
  /// The prediction for a sweep `dt` seconds after the last one (the last motion at constant velocity).
  Pose predict(double dt) const;
  /// The motion over one scan period of a sweep whose stamp-to-stamp motion took `dt` seconds.
  Pose perScanPeriod(const Pose& motion, double dt, double scan_period) const;
  std::shared_ptr<const Cloud> toSweepEnd(const std::shared_ptr<const FeatureSet>& owner, const Cloud& cloud,
                                          const Pose& motion) const;
  static void indexByRing(const Cloud& cloud, KdTree& all, std::vector<KdTree>& rings);
};

/// Moves every point of `in` (taken at its `time` within a sweep of `scan_period` seconds, during which
/// the sensor moved by `motion`: sweep start <- sweep end, at constant velocity) into the sensor frame at
/// the sweep end.
void deskewToSweepEnd(const Cloud& in, const Pose& motion, double scan_period, Cloud& out);

/// What deskewToSweepEnd does to one point taken at fraction `s` (0..1) of the sweep: the transform from
/// the sensor frame at that instant to the sensor frame at the sweep end. Its inverse puts a deskewed point
/// back where the sensor saw it.
Pose sweepEndFromPointTime(const Pose& motion, double s);

/// The frame's whole sweep in the sensor frame at the sweep end: `frame.full` itself where it needs no
/// deskewing (shared), else a deskewed copy. Null without a full cloud.
std::shared_ptr<const Cloud> fullAtSweepEnd(const OdometryFrame& frame);

/// Index of the first point of every ring in a ring-ordered cloud; entry r+1 ends ring r. Sized to the
/// largest ring present plus two.
std::vector<int> ringBegins(const Cloud& ring_ordered);

}  // namespace aloam
