// One mapping run as a node serves it: the map and its registration (LaserMapping), the time policy and the
// resets, the correction for the full-rate answer, the recorded trajectory, and the clouds a node shows. The
// mapping nodelet is a shell over this; aloam_offline and the tests use it without ROS.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "aloam_nodelet/core/laser_mapping.h"
#include "aloam_nodelet/core/loop_closure.h"
#include "aloam_nodelet/core/stamp_check.h"

namespace aloam
{
struct MappingSessionConfig
{
  LaserMappingConfig mapping;
  StampCheckConfig stamps;
  /// Poses kept for saving the trajectory (28 h at 10 Hz, 136 MB); beyond it the oldest tenth goes at once.
  std::size_t trajectory_max_poses = 1'000'000;
  /// Loop closure (closeLoops()); off: closeLoops() does nothing.
  bool loop_closure = false;
  LoopClosureConfig loop;
};

/// What closeLoops() did, for the node's logs and outputs.
struct LoopStep
{
  bool offered = false;  ///< a mapped frame was offered to the loop closure
  LoopUpdate update;
  double build_ms = 0.0;    ///< building the corrected map, off the core lock (accepted loops only)
  double rebuild_ms = 0.0;  ///< swapping it in, the next submap and the trajectory rewrite, under the core lock
};

/// What the session made of an arriving frame (admit()): the time policy's verdict (FrameAdmission; a
/// reset it reports is applied at the frame's registration) and the full-rate answer.
struct Admission : StampAdmission
{
  Pose corrected;  ///< map <- sensor for the full-rate answer (latest correction)
};

/// Counters and the last frame's figures, for diagnostics.
struct MappingSessionStats
{
  MappingResult last;  ///< map figures as of the last map update
  std::size_t frames_registered = 0;
  std::size_t frames_in_map = 0;  ///< registered since the map (re)started
  std::size_t frames_mapped = 0;
  std::size_t degraded = 0;
  std::size_t remapped = 0;
  std::size_t odometry_restarts = 0;
  std::size_t evicted_cubes = 0;
  std::size_t trajectory_dropped = 0;  ///< oldest poses dropped beyond trajectory_max_poses
  StampCounts stamps;
  LoopClosureStats loops;
  double last_build_ms = 0.0;    ///< the last corrected map's building (off the core lock)
  double last_rebuild_ms = 0.0;  ///< ... and what then held the core lock
};

/// The poses of the registered frames (map <- sensor) and their stamps, bounded.
struct RecordedTrajectory
{
  std::vector<Pose> poses;
  std::vector<double> stamps;

  /// The poses relative to the first (KITTI's convention: the first pose is the identity).
  std::vector<Pose> relativeToFirst() const;
};

/// Thread-safe: admit() takes a short lock of its own, so the full-rate answer never waits for a
/// registration; everything else serializes on the session's core lock.
class MappingSession
{
public:
  /// `executor`: the mapping stage's (see LaserMapping); null: the stage makes its own.
  explicit MappingSession(const MappingSessionConfig& config = {}, std::shared_ptr<Executor> executor = nullptr);

  /// The pose path, first step (cheap): applies the time policy to the frame's stamp, detects an
  /// odometry restart, and returns the full-rate answer. A reset it decides takes effect at the next
  /// registerFrame(), so the answer is corrected by nothing once a reset is pending.
  Admission admit(const OdometryFrame& frame, std::int64_t stamp_ns);

  /// The pose path, second step: adds the previous frame to the map if that is still pending (updateMap()),
  /// applies a pending reset, and registers `frame` against the map. The map itself is unchanged until
  /// updateMap(), so the pose can be published first.
  MappingResult registerFrame(const OdometryFrame& frame);

  /// After the pose: the last registered frame joins the map and the next submap is indexed. Returns
  /// false when there was nothing to add. `added` receives that frame and its completed result.
  bool updateMap(OdometryFrame* added = nullptr, MappingResult* result = nullptr);

  /// After the pose and the map update: offers the last mapped frame to the loop closure. Verification, the
  /// graph solve and building the corrected map run outside the core lock, so registrations go on meanwhile;
  /// the lock is taken to swap the corrected map in and rewrite the recorded trajectory.
  /// Call from one thread (the stage's lane).
  LoopStep closeLoops();
  void setLoopClosure(bool enabled, const LoopClosureConfig& config);
  bool loopClosureEnabled() const;

  /// Continues a saved graph (needs loop closure on): its keyframes are rebuilt into the map (off the core
  /// lock) and become loop targets, and this run's keyframes join the same graph as a new session
  /// (LoopClosure::importGraph). `initial` is map <- odometry world, the saved map's pose of where this
  /// run's odometry starts (its first sweep); the identity when the run starts where the saved one started.
  /// Starts a new map and trajectory as a reset does, so call it before the first frame. Returns what was
  /// adapted (LoopClosure::importGraph); throws std::logic_error when loop closure is off and
  /// std::invalid_argument for an inconsistent graph, in both cases changing nothing.
  std::vector<std::string> loadGraph(LoopGraph graph, const Pose& initial);
  /// The loop closure's graph as it stands (keyframes at their corrected poses), for saving
  /// (writeGraphFile). Waits for loop work in progress.
  LoopGraph exportGraph() const;

  /// A new map starts before the next registration (service call).
  void requestReset();

  /// Applies a new configuration after adding the pending frame (a new cube size re-buckets the map
  /// without losing points). Returns the map's point count before and after.
  std::pair<std::size_t, std::size_t> setMappingConfig(const LaserMappingConfig& config);
  LaserMappingConfig mappingConfig() const;
  void setMaxGapSweeps(double sweeps);

  /// The clouds a node shows, in the map frame: `cloud` moved by `pose`; the cubes around `pose`; the map.
  static Cloud toMap(const Cloud& cloud, const Pose& pose);
  Cloud surround(const Pose& pose) const;
  /// Calls `read(const CubeMap&)` under the core lock, after adding the pending frame (saving, publishing
  /// the whole map) and returns what it returns.
  template <typename Read>
  auto withMap(Read&& read)
  {
    std::lock_guard<std::mutex> lock(core_mutex_);
    updateMapLocked(nullptr, nullptr);
    return read(mapping_.map());
  }

  RecordedTrajectory trajectory() const;
  MappingSessionStats stats() const;

private:
  void resetLocked();
  bool updateMapLocked(OdometryFrame* added, MappingResult* result);

  // Admission state (admission_mutex_): the full-rate answer must not wait for a registration.
  mutable std::mutex admission_mutex_;
  FrameAdmission admission_;
  Pose correction_;  // map <- odometry world, as of the last registration
  bool reset_pending_ = false;

  // Everything else (core_mutex_).
  mutable std::mutex core_mutex_;
  std::size_t trajectory_max_poses_;
  LaserMapping mapping_;
  RecordedTrajectory trajectory_;
  OdometryFrame unmapped_;  // registered, not yet in the map
  bool has_unmapped_ = false;
  MappingSessionStats stats_;

  // Loop closure: the last mapped frame waiting for closeLoops() (core_mutex_), and the loop closure itself
  // (loop_mutex_, taken before core_mutex_ when both are needed).
  struct MappedFrame
  {
    double stamp = 0.0;
    Pose pose;
    std::shared_ptr<const Cloud> corners, surfs, full;
    std::size_t epoch = 0;  ///< map_epoch_ when it was registered
  };
  std::optional<MappedFrame> to_offer_;
  std::size_t map_epoch_ = 0;  ///< map rebuilds and resets so far: a frame of an older epoch is not offered
  bool loop_enabled_ = false;
  bool loop_reset_pending_ = false;  ///< the map was reset: the loop closure starts over too
  /// The loop closure's keyframe rule as of its last frame (LoopClosure::keyframeReference), so that a frame
  /// that cannot become a keyframe is not copied for it.
  std::optional<Pose> keyframe_reference_;
  LoopClosureConfig loop_gate_;
  mutable std::mutex loop_mutex_;
  LoopClosure loops_;
};

}  // namespace aloam
