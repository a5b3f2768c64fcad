// Loop closure for the mapping stage: keyframes of the mapped trajectory, loop candidates near the pose
// estimate and by place descriptor, verification by this package's own scan-to-map matching, and a pose
// graph whose solution moves the keyframes (and so the map) to agree where a place is revisited. ROS-free;
// the caller (Pipeline, MappingSession) rebuilds the map from the corrected keyframes.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "aloam_nodelet/core/laser_mapping.h"
#include "aloam_nodelet/core/pose_graph.h"
#include "aloam_nodelet/core/scan_context.h"

namespace aloam
{
struct LoopClosureConfig
{
  double keyframe_distance = 1.0;               ///< a keyframe every this many metres of path ...
  double keyframe_angle = 10.0 * M_PI / 180.0;  ///< ... or this much rotation (rad)
  double keyframe_corner_leaf = 0.4;            ///< voxel leaf of a keyframe's stored edge points (m)
  double keyframe_surf_leaf = 0.8;              ///< ... and plane points
  /// Memory the keyframes' clouds may take; beyond it the oldest lose them (their pose stays in the graph,
  /// but they can no longer be a loop target nor rebuild the map). 256 MiB: about 1,300 HDL-64 keyframes
  /// or 6,000 VLP-16 ones.
  std::size_t max_keyframe_bytes = std::size_t(256) << 20;
  /// No loop between keyframes closer than this in time (s) or along the path (m).
  double min_loop_separation_time = 30.0;
  double min_loop_separation_path = 30.0;
  /// Nearby candidates: keyframes within search_radius + search_radius_growth * (path since the last
  /// accepted loop, or since the start) of the current estimate.
  double search_radius = 10.0;
  double search_radius_growth = 0.02;
  /// Descriptor candidates (Scan Context): the closest ring keys, accepted below this descriptor distance.
  bool use_descriptor = true;
  ScanContextConfig descriptor;
  int descriptor_candidates = 5;
  double max_descriptor_distance = 0.25;
  /// Verification: the target's neighbours within this radius (m, by their corrected poses) form the
  /// submap the current keyframe is registered against.
  double submap_radius = 20.0;
  /// Coarse search before the registration: positions within +-coarse_radius (coarse_step apart) and yaws
  /// within +-coarse_yaw (coarse_yaw_step apart) of the start, scored on every 4th point.
  double coarse_radius = 3.0;
  double coarse_step = 1.5;
  double coarse_yaw = 10.0 * M_PI / 180.0;
  double coarse_yaw_step = 5.0 * M_PI / 180.0;
  /// Correspondence searches of the registration (each followed by a solve).
  int outer_iterations = 6;
  /// Acceptance: inlier share (matches within inlier_residual over points offered), mean residual of the
  /// matches, and a registration along every direction (mapping's MappingStatus::kOk).
  double inlier_residual = 0.2;
  double min_inlier_share = 0.35;
  double max_mean_residual = 0.1;
  /// A registration weak along at most this many directions, each a translation (mapping's
  /// MappingStatus::kRemapped, such as a corridor's axis), is accepted too; its loop edge carries along each
  /// weak direction only that direction's share of the constraint (loopSqrtInformation). 0: only fully
  /// constrained registrations.
  int max_weak_directions = 2;
  /// A weak direction whose rotation part (of the unit 6-vector, rotations scaled by the lever arm, see
  /// DegenerateDirection) exceeds this is rejected: along it the loop keeps the current keyframe's own
  /// attitude error (a narrow corridor's up-down-with-roll direction carried 1.5-2.6 deg, docs/loop_closure.md).
  double max_weak_rotation = 0.25;
  /// The correction a loop implies must be one that drift could have made over the path between the two
  /// keyframes: at most max_correction + max_correction_rate * path (m), and the rotation at most
  /// max_correction_angle + max_correction_angle_rate * path (rad). Rejects look-alike places far away.
  double max_correction = 2.0;
  double max_correction_rate = 0.03;
  double max_correction_angle = 5.0 * M_PI / 180.0;
  double max_correction_angle_rate = 0.1 * M_PI / 180.0;
  /// After an accepted loop, the next is tried this many metres of path later.
  double loop_spacing = 5.0;
  /// Pose graph: odometry edges' sigmas (translation m, rotation rad) per metre of path between the two
  /// keyframes, plus a floor; loop edges' sigmas from the registration's mean residual, at least these.
  double odometry_sigma_translation = 0.02;
  double odometry_sigma_rotation = 0.002;
  double loop_sigma_translation = 0.1;
  double loop_sigma_rotation = 0.01;
  /// Loops the solved graph disagrees with by more than this many sigmas are left out (while two or more
  /// remain), and the final solve puts a Cauchy loss of this scale on the loops (PoseGraphOptions).
  double loop_outlier_error = 5.0;
  double loop_loss_scale = 5.0;
  int graph_iterations = 50;
  /// A run that continues a loaded graph (LoopClosure::importGraph): its first keyframe is held near the
  /// nearest loaded keyframe, where the run's initial pose put it, by an edge of these sigmas (m, rad). A
  /// weak prior that only keeps the graph in one piece; the verified tie (a loop edge) is what moves it.
  double session_anchor_sigma_translation = 1.0;
  double session_anchor_sigma_rotation = 0.05;
  /// The matching used to verify loops (leaf sizes, neighbours); LoopClosure sets it frozen.
  LaserMappingConfig matching;
};

/// A mapped keyframe: its pose in the corrected map, and its clouds in the sensor frame.
struct Keyframe
{
  double stamp = 0.0;
  Pose pose;          ///< map <- sensor, as corrected by the pose graph
  double path = 0.0;  ///< metres travelled from the first keyframe of its run
  /// The run that made it: 0 the first, 1 the run that loaded its graph, and so on. Keyframes of different
  /// runs always count as separated (their stamps and paths are not comparable).
  int session = 0;
  std::shared_ptr<const Cloud> corners, surfs;  ///< null once dropped (max_keyframe_clouds)
  ScanContext descriptor;
};

enum class LoopSource
{
  kNearby,      ///< near the current pose estimate
  kDescriptor,  ///< found by the place descriptor
  /// The first keyframe of a run over a loaded graph against the nearest loaded keyframe: the tie of the
  /// new run to the old graph.
  kSessionStart,
};

/// "nearby", "descriptor" or "session start".
const char* toString(LoopSource source);

/// One tried loop: accepted, or rejected with the reason.
struct LoopRecord
{
  std::size_t from = 0;  ///< the target (older) keyframe
  std::size_t to = 0;    ///< the current keyframe
  double from_stamp = 0.0, to_stamp = 0.0;
  LoopSource source = LoopSource::kNearby;
  bool accepted = false;
  std::string reason;  ///< why it was rejected ("" when accepted); verification or, later, the pose graph
  double descriptor_distance = 1.0;
  MatchFitness fitness;
  double correction_m = 0.0;    ///< how far the loop moves the current keyframe (m)
  double correction_rad = 0.0;  ///< ... and turns it
  Pose relative;                ///< from <- to, as registered (accepted loops)
  /// Directions the registration constrained only weakly, in the frame of `to` (accepted loops).
  std::vector<DegenerateDirection> weak;
};

/// What one offered frame did.
struct LoopUpdate
{
  bool keyframe = false;          ///< the frame became a keyframe
  std::vector<LoopRecord> tried;  ///< candidates verified for it
  bool optimized = false;         ///< an accepted loop moved the graph
  /// The corrected map <- the map before the optimization, at the newest keyframe: applied to the
  /// mapping's correction it moves the next poses into the corrected map.
  Pose correction;
  std::vector<Pose> keyframes_before;  ///< with `optimized`: every keyframe's pose before the solve
  PoseGraphSummary graph;
  double verify_ms = 0.0;
};

/// How the current run is tied to a loaded graph (LoopClosure::importGraph).
enum class SessionTie
{
  kNone,     ///< no graph loaded: the run is the graph's first
  kPending,  ///< loaded; the run's first keyframe is not made yet
  kTied,     ///< the first keyframe registered against the loaded keyframes and the loop edge accepted
  kNotTied,  ///< that registration failed the loop checks (LoopClosureStats::tie_reason): no tie edge
};

/// "none", "pending", "tied", "not tied".
const char* toString(SessionTie tie);

/// The state a later run continues (LoopClosure::exportGraph / importGraph; graph_file.h stores it).
struct LoopGraph
{
  std::vector<Keyframe> keyframes;    ///< node i of the pose graph is keyframe i, at its corrected pose
  std::vector<PoseGraphEdge> edges;   ///< odometry, loop and session edges, with their enabled flags
  ScanContextConfig descriptor;       ///< what the keyframes' descriptors were made with
  double keyframe_corner_leaf = 0.4;  ///< the voxel leaves of the keyframes' clouds (m)
  double keyframe_surf_leaf = 0.8;
};

struct LoopClosureStats
{
  std::size_t keyframes = 0;
  std::size_t keyframes_loaded = 0;  ///< of those, loaded from a saved graph (importGraph)
  SessionTie tie = SessionTie::kNone;
  std::string tie_reason;  ///< kNotTied: why; kTied: the keyframe it tied to
  std::size_t keyframes_with_clouds = 0;
  std::size_t cloud_bytes = 0;  ///< memory of the kept keyframe clouds
  std::size_t tried = 0;
  std::size_t accepted = 0;
  std::size_t rejected = 0;
  std::size_t optimizations = 0;
  double last_optimize_ms = 0.0;
};

/// Whether a frame at `pose` has moved far enough from `last`, the previous keyframe's input pose, to become a
/// keyframe (LoopClosureConfig::keyframe_distance, keyframe_angle).
bool isKeyframeStep(const Pose& last, const Pose& pose, const LoopClosureConfig& config);

/// A loop edge's square-root information (PoseGraphEdge): the sigmas (translation m, rotation rad) along
/// the directions the registration constrained; along each weak one (in the frame of `to`, rotation parts as
/// the motion at `lever_arm` metres) only its share of that information, none where the share is unknown.
/// `relative`: the loop's rotation from <- to.
Eigen::Matrix<double, 6, 6> loopSqrtInformation(double sigma_translation, double sigma_rotation,
                                                const std::vector<DegenerateDirection>& weak,
                                                const Eigen::Quaterniond& relative, double lever_arm);

class LoopClosure
{
public:
  explicit LoopClosure(LoopClosureConfig config = {});

  const LoopClosureConfig& config() const { return config_; }
  /// Thresholds only; keyframes and graph stay.
  void setConfig(const LoopClosureConfig& config);

  /// Offers a mapped frame: `pose` (map <- sensor, in the map as corrected so far) and its sensor-frame
  /// edge and plane clouds. Far enough from the last keyframe, it becomes one, its loop candidates are
  /// verified, and an accepted loop re-solves the graph. `sweep` (optional, sensor frame): the whole sweep,
  /// which describes the place better than the features; the descriptor is made from it when given.
  LoopUpdate addFrame(double stamp, const Pose& pose, const Cloud& corners, const Cloud& surfs,
                      const Cloud* sweep = nullptr);

  /// A copy of the graph (keyframes with their clouds shared, edges, settings), for saving.
  LoopGraph exportGraph() const;
  /// Replaces everything by a saved graph: its keyframes become loop targets and map sweeps, its edges stay
  /// in the pose graph, and the next keyframe starts a new run (session) in the same graph, tied to the
  /// nearest loaded keyframe by a weak anchor edge and, when the registration verifies, by a loop edge.
  /// The caller's poses must be in the graph's map frame from then on. Returns what it had to adapt (e.g.
  /// descriptors made with other settings are remade from the keyframe clouds). Throws
  /// std::invalid_argument, changing nothing, when the graph is inconsistent (an edge to no keyframe, a
  /// non-finite pose, an edge PoseGraphEdge::isUsable rejects).
  std::vector<std::string> importGraph(LoopGraph graph);
  /// Index of the current run's first keyframe (the number of loaded keyframes).
  std::size_t sessionBegin() const { return session_begin_; }

  const std::vector<Keyframe>& keyframes() const { return keyframes_; }
  /// Every loop tried so far, in order.
  const std::vector<LoopRecord>& history() const { return history_; }
  LoopClosureStats stats() const;
  /// The keyframes' clouds at their corrected poses, for rebuilding the map.
  std::vector<MapSweep> mapSweeps() const;
  /// Index of the current run's newest keyframe at or before `stamp` (the run's first when none is older;
  /// keyframes().size() while the run has none). Loaded keyframes are never returned.
  std::size_t keyframeAt(double stamp) const;
  /// The input pose the next keyframe is measured from (isKeyframeStep); none before the run's first keyframe,
  /// when any frame becomes one.
  std::optional<Pose> keyframeReference() const;
  /// Moves poses recorded at `stamps` as the last optimization moved their keyframes: each follows the
  /// keyframe keyframeAt(its stamp), from its pose in `before` (LoopUpdate::keyframes_before) to its pose now.
  void correctPoses(const std::vector<double>& stamps, const std::vector<Pose>& before, std::vector<Pose>& poses) const;
  const PoseGraph& graph() const { return graph_; }
  void reset();

private:
  LoopClosureConfig config_;
  std::vector<Keyframe> keyframes_;
  PoseGraph graph_;
  std::vector<LoopRecord> history_;
  std::vector<std::pair<std::size_t, std::size_t>> loop_edges_;  ///< (graph edge, history_ index) of each loop
  /// The newest keyframe's pose in the frame the caller's poses are given in (after an optimization that
  /// frame is the corrected one): odometry edges are measured from it.
  Pose last_input_;
  double last_loop_path_ = -1.0;  ///< path of the last accepted loop's current keyframe (< 0: none yet)
  std::size_t optimizations_ = 0;
  double last_optimize_ms_ = 0.0;
  int session_ = 0;                    ///< the current run's session number
  std::size_t session_begin_ = 0;      ///< its first keyframe's index (loaded keyframes come before)
  std::size_t tie_record_ = SIZE_MAX;  ///< history_ index of the tie of the current run to a loaded graph

  bool isKeyframe(const Pose& pose) const;
  /// The nearest keyframe of an earlier run (with clouds when `with_clouds`); keyframes_.size() if none.
  std::size_t nearestLoaded(const Eigen::Vector3d& position, bool with_clouds) const;
  void dropOldClouds();
  /// Candidate targets for the newest keyframe (nearby first, then by descriptor), with their sources.
  std::vector<LoopRecord> candidates() const;
  /// Registers the newest keyframe against the target's neighbourhood and decides.
  void verify(LoopRecord& record) const;
  bool separated(const Keyframe& a, const Keyframe& b) const;
};

}  // namespace aloam
