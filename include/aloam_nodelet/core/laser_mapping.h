// LOAM laser mapping: scan-to-map refinement of the odometry pose against a cube map.
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Eigenvalues>

#include "aloam_nodelet/core/cube_map.h"
#include "aloam_nodelet/core/executor.h"
#include "aloam_nodelet/core/kd_tree.h"
#include "aloam_nodelet/core/laser_odometry.h"
#include "aloam_nodelet/core/pose.h"
#include "aloam_nodelet/core/pose_solver.h"

namespace aloam
{
struct LaserMappingConfig
{
  double cube_size = 50.0;        ///< edge of a map cube (m)
  int submap_half_xy = 2;         ///< submap: cubes on each side of the robot's cube, x and y
  int submap_half_z = 1;          ///< ... and z
  double corner_leaf_size = 0.4;  ///< voxel leaf for edge points, scan and map (m)
  double surf_leaf_size = 0.8;    ///< voxel leaf for plane points, scan and map (m)
  /// Leaves follow the scene's size: when the median range of a sweep's plane points is below
  /// leaf_reference_range, both leaves shrink by the power of two (1/2, 1/4, ...) nearest to median /
  /// reference, down to this scale. Leaves sized for a street keep a handful of points per wall of a 2 m
  /// corridor. Changes need a margin past the midpoint between two scales, so that the map is not
  /// re-indexed back and forth. 1: fixed leaves (A-LOAM).
  double leaf_min_scale = 0.25;
  double leaf_reference_range = 16.0;  ///< m; see leaf_min_scale
  int max_iterations = 4;              ///< Levenberg-Marquardt iterations per solve
  int outer_iterations = 2;            ///< correspondence searches per frame, each followed by a solve
  /// Searches for a frame odometry found hard (OdometryFrame::hard(): motion hypotheses tried, degraded
  /// or remapped): its pose is less certain, so mapping searches more often from it. 4 measured better
  /// than 2 on the simulated yaw bursts, 8 no better (docs/accuracy.md#measurements-behind-defaults).
  /// <= outer_iterations: every frame alike (A-LOAM).
  int hard_frame_outer_iterations = 4;
  /// true: the first sweep, whose motion is unknown and which therefore could not be deskewed
  /// (OdometryFrame::distorted), starts the map as it is. Off: on hand-held walks it measured as noise,
  /// and on a car the undeskewed first sweep warps the map (test_laser_mapping; figures in
  /// docs/accuracy.md#measurements-behind-defaults).
  bool insert_distorted_first = false;
  /// true: that distorted first sweep is held and goes into the map with the next sweep, deskewed then
  /// with the motion odometry solved for that next sweep (constant velocity across the two), so the map
  /// starts with the first sweep after all. false: it never enters the map (81f6493, --baseline).
  bool deskew_first_late = true;
  /// A later search of a frame keeps a point's match where its neighbours provably stay the same (see
  /// SearchMemo): the same trajectory up to rounding, half the later searches on KITTI. false: every
  /// search searches (A-LOAM; the tests' baseline).
  bool reuse_searches = true;
  /// A sweep in which the motion changed (odometry's motion differs from the previous sweep's by more than
  /// span_motion_change_deg or span_motion_change_m) was deskewed with a motion that is wrong within it:
  /// after the rigid solve, mapping solves its start and end pose (SweepSpan, constant velocity between
  /// them), the start held to where the sensor was a sweep before (on the path from the previous sweep's
  /// end) by span_start_weight, and re-deskews the sweep with that motion before it enters the map. Only
  /// with deskewing; false: one pose per sweep (A-LOAM).
  bool sweep_span = true;
  double span_motion_change_deg = 1.0;
  double span_motion_change_m = 0.05;
  /// How strongly the start stays where the previous sweep ended, as that many point matches would hold it.
  /// Weak: the previous end may be wrong by what that sweep's own change of motion left in it.
  double span_start_weight = 3.0;
  int span_iterations = 2;  ///< correspondence searches of the span solve
  /// Only sweeps whose rigid solve pinned every direction at least this well (constraint, as min_constraint)
  /// are spanned: the span has no handling of weak directions, and in corridors it wandered along the axis
  /// where the rigid solve held the weak directions (docs/accuracy.md, "The sweep span").
  double span_min_constraint = 100.0;
  int line_neighbours = 5;  ///< map points fitted per edge point (A-LOAM: 5)
  /// Farthest fitted neighbour (m^2), lines and planes. A-LOAM uses 1 m^2; with 0.8 m plane voxels five
  /// neighbours often lie just beyond 1 m, and 2 m^2 measured better on KITTI 00 (drift 1.28 % vs 1.30 %).
  double line_max_sq_distance = 2.0;
  double line_eigen_ratio = 3.0;  ///< a line needs its largest eigenvalue this times the next
  /// An edge point's line that crosses the scan cone of the point (the cone its beam sweeps as the sensor
  /// spins) at less than this angle (deg) leaves the point free across the rings: the match measures only
  /// the offset along the other direction perpendicular to the line. Such lines are mostly traces of one
  /// ring on a smooth surface (returns whose curvature comes from their spacing, or from a corner or gap a
  /// few returns away), and where a ring meets a surface moves with the sensor: matched in full, they
  /// pitched the pose nose up and the map climbed on flat ground (docs/accuracy.md#vertical-drift-on-flat-
  /// ground). 0: every residual in full (A-LOAM).
  double line_ring_crossing_deg = 30.0;
  /// ... for points at least this far (m). Nearer, the rings lie close together on a surface and lines
  /// along them are mostly real edges (ceiling and door lines indoors), which keep their full residual.
  double line_ring_crossing_min_range = 15.0;
  /// Map points fitted per plane point. On sparse maps (16 beams) five neighbours are often one scan line
  /// plus a stray point, which fit a plane exactly with a false normal near wall bases and curbs. More
  /// neighbours fixed that on a synthetic VLP-16 drive but cost accuracy on KITTI, so the default stays
  /// A-LOAM's count (docs/accuracy.md#measurements-behind-defaults).
  int plane_neighbours = 5;
  double plane_max_sq_distance = 2.0;
  double plane_max_distance = 0.2;  ///< every neighbour within this of the fitted plane (m)
  /// The neighbours must spread in two directions: second eigenvalue at least this times the largest (0.3
  /// measured best of 0.05 / 0.15 / 0.3 on KITTI and on synthetic VLP-16 and HDL-64 drives).
  double plane_min_spread_ratio = 0.3;
  double huber_delta = 0.1;            ///< robust loss scale (m)
  double inlier_residual = 0.0;        ///< > 0: count inliers (see MatchSolveOptions); mapping does not need it
  int min_map_corners = 10;            ///< submap needs this many edge points to register against
  int min_map_surfs = 50;              ///< ... and this many plane points
  int min_correspondences = 20;        ///< fewer matches: keep the prediction, report degraded
  double min_constraint = 25.0;        ///< weaker constraint (see LaserOdometryConfig): keep the prediction
  double constraint_lever_arm = 10.0;  ///< metres; see PoseProblem::constraintStrength
  /// Degeneracy per direction (see LaserOdometryConfig::degeneracy_remap): the prediction is kept only
  /// along the directions weaker than min_constraint. false: any weak direction keeps the whole prediction.
  bool degeneracy_remap = true;
  /// With degeneracy_remap, a weak direction keeps the share eigenvalue / min_constraint of the solve's
  /// step instead of none (PoseProblem::remap), as in odometry.
  bool soft_remap = true;
  /// More degenerate directions than this: the whole prediction is kept (see MatchSolveOptions::max_degenerate).
  int max_degenerate_directions = 3;
  double eviction_radius = 1000.0;  ///< cubes farther than this from the robot are dropped (m); <= 0 keeps all
  int threads = 2;                  ///< threads sharing the correspondence search (results do not depend on it)
};

enum class MappingStatus
{
  kOk,
  kMapTooSmall,  ///< the map near the robot has too few points (start-up): prediction used
  kDegraded,     ///< too few correspondences or a divergent solve: prediction used
  kRemapped,     ///< some directions degenerate: prediction kept along them, the solve along the others
};

struct MappingResult
{
  double stamp = 0.0;
  Pose pose;        ///< map <- sensor at the sweep end
  Pose correction;  ///< map <- odometry world, for correcting odometry poses between mapped frames
  MappingStatus status = MappingStatus::kMapTooSmall;
  int corner_matches = 0;
  int plane_matches = 0;
  bool span_solved = false;  ///< the sweep's start and end were solved (LaserMappingConfig::sweep_span)
  int reused_searches = 0;   ///< searches skipped because an earlier one of the frame still held (SearchMemo)
  double constraint = 0.0;   ///< how well the matches pin the pose down (0: degenerate)
  /// Directions the matches did not pin down, in the sensor frame (see OdometryFrame::degenerate).
  std::vector<DegenerateDirection> degenerate;
  std::size_t map_corners = 0;
  std::size_t map_surfs = 0;
  std::size_t cubes = 0;
  std::size_t evicted_cubes = 0;  ///< cubes evicted while processing this frame
  double leaf_scale = 1.0;        ///< the leaves of this frame: the configured ones times this
};

/// How well a sweep at a pose fits the submap: the figures localization decides with.
struct MatchFitness
{
  int tried = 0;               ///< points offered (edge and plane points)
  int matched = 0;             ///< points that found a line or plane in the map
  int inliers = 0;             ///< matched within the inlier residual
  double inlier_share = 0.0;   ///< inliers / tried
  double mean_residual = 0.0;  ///< mean distance of the matched points to their line or plane (m)
};

/// A sweep's clouds (sensor frame) at its pose in the map (LaserMapping::rebuildMap).
struct MapSweep
{
  std::shared_ptr<const Cloud> corners, surfs;
  Pose pose;  ///< map <- sensor
};

/// A start pose and how well a sweep fits the map from there (inlier share).
struct ScoredPose
{
  Pose pose;
  double score = 0.0;
};

/// The starts of a coarse search: positions within +-radius of `centre` (step apart) along the map's x and y,
/// each turned within +-yaw (yaw_step apart) about the map's z.
std::vector<Pose> poseGrid(const Pose& centre, double radius, double step, double yaw, double yaw_step);

class LaserMapping
{
public:
  /// Parallel regions run on `executor` (a pipeline shares one among its stages); without one the stage
  /// makes its own, sized from the configuration's `threads`.
  explicit LaserMapping(LaserMappingConfig config = {}, std::shared_ptr<Executor> executor = nullptr);

  const LaserMappingConfig& config() const { return config_; }
  const std::shared_ptr<Executor>& executor() const { return executor_; }
  /// Applies a new configuration; a new cube size re-buckets the map without losing points.
  void setConfig(const LaserMappingConfig& config);

  /// Refines the frame's odometry pose against the map, then adds the frame's features to the map:
  /// registerFrame() then updateMap().
  MappingResult process(const OdometryFrame& frame);

  /// Scan-to-map registration: the frame's pose in the map (and the new correction). The map is not
  /// changed yet, so a node can publish the pose before the map work.
  MappingResult registerFrame(const OdometryFrame& frame);
  /// Adds the last registered frame to the map, evicts far cubes, and indexes the submap around the new
  /// pose for the next registration; completes `result`'s map figures.
  void updateMap(MappingResult& result);

  /// The odometry pose corrected into the map frame with the latest correction.
  Pose correct(const Pose& odometry_pose) const { return correction_ * odometry_pose; }
  const Pose& correction() const { return correction_; }
  const CubeMap& map() const { return map_; }
  std::size_t totalEvictedCubes() const { return evicted_total_; }
  void reset();

  /// Loop closure: replaces the map by these sweeps at their (corrected) poses, merged into voxels as the
  /// map merges every sweep, and moves the frame last added (and so the next prediction) by `change`
  /// (corrected map <- map before): the correction becomes change * correction. Call after updateMap().
  void rebuildMap(const std::vector<MapSweep>& sweeps, const Pose& change);
  /// The same with the map built beforehand (buildMap), so that the building need not hold the stage.
  void replaceMap(CubeMap map, const Pose& change);
  /// A map of these sweeps as rebuildMap() makes it, with the configuration's cube and leaf sizes (rebuildMap()
  /// scales the leaves as the current frame's are).
  static CubeMap buildMap(const std::vector<MapSweep>& sweeps, const LaserMappingConfig& config);
  /// A run that continues a saved map: reset(), then `map` (buildMap of the saved keyframes) is the map and
  /// `correction` (map <- odometry world: where the run's odometry starts in the saved map) predicts the
  /// first frame. A distorted first sweep (its motion unknown) then keeps that prediction and never enters
  /// the map; registration starts with the next sweep.
  void startIn(CubeMap map, const Pose& correction);

  // Localization in a saved map (see Localizer). None of these is used while mapping.

  /// Replaces the map by these points (map frame), kept as they are (no voxel merging).
  void loadMap(const Cloud& corners, const Cloud& surfs);
  /// Frozen: registerFrame() never queues the sweep for the map and updateMap() never inserts nor
  /// evicts; it only indexes the submap around the new pose.
  void setFrozen(bool frozen) { frozen_ = frozen; }
  bool frozen() const { return frozen_; }
  /// The correction the next registerFrame() predicts with (map <- odometry world).
  void setCorrection(const Pose& correction) { correction_ = correction; }
  /// Indexes the submap around a position unless it is indexed already.
  void prepareSubmapAround(const Eigen::Vector3d& position);
  /// The fit of sensor-frame clouds at `pose` against the current submap, every `stride`th point.
  MatchFitness fitness(const Cloud& corners, const Cloud& surfs, const Pose& pose, double inlier_residual,
                       int stride = 1) const;
  /// The `keep` starts (at least one) from which the sensor-frame clouds fit the map best, best first: the
  /// inlier share within inlier_residual of every `stride`th point, in the submap around each start.
  std::vector<ScoredPose> bestStarts(const Cloud& corners, const Cloud& surfs, const std::vector<Pose>& starts,
                                     double inlier_residual, int stride, int keep);
  /// The downsampled clouds of the last registerFrame().
  const Cloud& registeredCorners() const { return corner_stack_; }
  const Cloud& registeredSurfs() const { return surf_stack_; }

private:
  /// A point's last neighbour search in the frame being solved. Its k nearest map points stay the k
  /// nearest while the query moves by less than half the slack: each of them is then at most d_k + delta
  /// away, every other point at least d_(k+1) - delta (or beyond the search radius). The match, which
  /// depends only on those points, then holds, and the search is skipped (about half of the later
  /// searches on KITTI, trajectory unchanged: docs/performance.md).
  struct SearchMemo
  {
    float query[3];        ///< where the point was searched from (map frame)
    float slack = -1.0f;   ///< d_(k+1) (or the search radius) - d_k, less a rounding margin; < 0: none
    bool matched = false;  ///< the verdict of that search
    int reused = 0;        ///< searches it saved
  };

  LaserMappingConfig config_;
  std::shared_ptr<Executor> executor_;
  bool frozen_ = false;
  double leaf_scale_ = 1.0;  ///< see LaserMappingConfig::leaf_min_scale
  CubeMap map_;
  Pose correction_;
  Pose last_motion_;                ///< odometry's motion of the previous frame (see motionChanged) ...
  bool last_motion_known_ = false;  ///< ... unless that was the first
  std::size_t evicted_total_ = 0;
  // The submap (cubes around the robot) and its search trees, ready before the frame that needs them.
  Cloud submap_corners_, submap_surfs_;
  KdTree corner_tree_;
  KdTree surf_tree_;
  CubeIndex submap_centre_;
  bool submap_ready_ = false;
  // The registered frame, downsampled, waiting for updateMap(), and its points' searches in solve().
  Cloud corner_stack_, surf_stack_;
  std::vector<SearchMemo> corner_memo_, surf_memo_;
  Pose pending_pose_;
  bool pending_insert_ = false;
  bool run_started_ = false;  ///< a frame was registered since reset() / startIn()
  bool continued_ = false;    ///< the map was loaded by startIn()
  // A distorted first sweep waiting for the next sweep's motion (deskew_first_late), and, once that is
  // known, its deskewed and downsampled clouds waiting for updateMap().
  struct HeldSweep
  {
    std::shared_ptr<const Cloud> corners, surfs;
    Pose pose;
    double stamp = 0.0;
  };
  std::optional<HeldSweep> held_first_;
  Cloud first_corners_, first_surfs_;
  Pose first_pose_;
  bool pending_first_ = false;

  double cornerLeaf() const { return config_.corner_leaf_size * leaf_scale_; }
  double surfLeaf() const { return config_.surf_leaf_size * leaf_scale_; }

  /// Deskews the held first sweep with `frame`'s motion and queues it for updateMap().
  void releaseHeldFirst(const OdometryFrame& frame);

  /// The k nearest map points of a query within a radius, their centroid and principal axes.
  struct Neighbourhood
  {
    std::vector<int> index;
    Eigen::Vector3d centroid;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
  };

  /// search() (which may record its slack in `memo`), or, when `memo` shows its last search from nearby
  /// still holds, that search's verdict (the caller's match slot then still holds its match).
  template <typename Search>
  static bool recall(SearchMemo* memo, const Point& query, Search&& search);

  MatchSolveResult solve(Pose& pose, int outer_iterations, MappingResult& result);
  /// Whether the frame's motion differs enough from the previous frame's for solveSpan().
  bool motionChanged(const OdometryFrame& frame) const;
  /// Solves the sweep's start and end pose (SweepSpan) from the solved end `pose` and the previous sweep's
  /// end (from `prediction`), re-deskews the downsampled clouds with that motion and moves `pose` to the
  /// new end. False (nothing changed) when the sweep is not deskewed, or the solve fails or runs off.
  bool solveSpan(const OdometryFrame& frame, const Pose& prediction, Pose& pose);
  /// The k nearest map points of `query` within the radius; with `memo`, its slack is recorded too.
  static bool fitNeighbours(const KdTree& tree, const Cloud& cloud, const Point& query, int k, double max_sq_distance,
                            Neighbourhood& fit, SearchMemo* memo = nullptr);
  /// The point's line (plane) at `pose`; with `memo`, the point's earlier match in this solve when it holds.
  bool matchEdge(const Point& p, const Pose& pose, LineMatch& match, SearchMemo* memo = nullptr) const;
  bool matchPlane(const Point& p, const Pose& pose, PlaneMatch& match, SearchMemo* memo = nullptr) const;
  void insert(const Pose& pose);
  void prepareSubmap(const CubeIndex& centre);
};

}  // namespace aloam
