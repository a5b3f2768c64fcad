// Localization in a saved map: the mapping stage's scan-to-map matching against a map that is loaded
// once and never changed, with a fitness measure, a localized / lost state and pose searches.
#pragma once

#include <cmath>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "aloam_nodelet/core/laser_mapping.h"
#include "aloam_nodelet/core/map_file.h"
#include "aloam_nodelet/core/stamp_check.h"

namespace aloam
{
struct LocalizerConfig
{
  /// The matching (leaf sizes, neighbours, solver). loadMap() takes the cube and leaf sizes from the map.
  LaserMappingConfig mapping;
  /// A match closer than this to its line or plane is an inlier (m).
  double inlier_residual = 0.2;
  /// Inlier share a frame needs to count as fitting (to become localized, and to recover when lost) ...
  /// On KITTI a sweep registered in its own map scores above it, one 20 m off below (docs/accuracy.md).
  double localized_share = 0.3;
  /// ... and the share below which a localized frame counts as not fitting: the gap is the hysteresis.
  double lost_share = 0.2;
  /// Mean distance of the matched points to their lines and planes a fitting frame must stay below (m);
  /// on KITTI a registered sweep stays well below it, one 20 m off lies above ...
  double max_mean_residual = 0.15;
  /// ... and the one a localized frame may reach before it counts as not fitting (hysteresis).
  double lost_mean_residual = 0.2;
  int frames_to_localize = 2;  ///< consecutive fitting frames: localizing -> localized
  int frames_to_lose = 3;      ///< consecutive frames not fitting: localizing or localized -> lost
  /// Correspondence searches per frame while not settled (not localized, or the last frame's mean residual
  /// above settled_residual): a start far off needs more of them.
  int converge_outer_iterations = 6;
  double settled_residual = 0.1;  ///< m; a registered KITTI sweep measured 0.08
  double settled_step = 0.1;      ///< m; registration moved the last pose at most this far from odometry's

  /// Search around a given pose (after setInitialPose and, when lost, every retry_every frames): positions
  /// on a square grid of this half-width and step (m), yaws within +-search_yaw by search_yaw_step (rad),
  /// each scored by the fitness of every search_stride-th point; the best search_refine are registered.
  double search_radius = 2.0;
  double search_step = 1.0;
  double search_yaw = 15.0 * M_PI / 180.0;
  double search_yaw_step = 5.0 * M_PI / 180.0;
  /// Inlier residual of the coarse scoring (m): a candidate up to half a step off still scores.
  double search_inlier_residual = 0.5;
  int search_stride = 4;
  int search_refine = 3;
  int retry_every = 10;  ///< lost: a search around the propagated pose every this many frames (0: never)

  /// No initial pose: search the whole map (global localization) on the first frames.
  bool global_localization = false;
  double global_spacing = 5.0;  ///< candidate positions at least this far apart (m)
  double global_yaw_step = 10.0 * M_PI / 180.0;
  int global_refine = 6;  ///< best coarse candidates searched around and registered
  /// Without a trajectory in the map file, candidates are a grid of this spacing over the ground (the
  /// lowest plane points of each cell), raised by the sensor height (m).
  double sensor_height = 1.73;
};

enum class LocalizationState
{
  kUninitialized,  ///< no pose yet: waiting for an initial pose (or a global search that found none)
  kLocalizing,     ///< an initial pose was given, the fit is not yet confirmed
  kLocalized,      ///< the sweeps fit the map
  kLost,           ///< they stopped fitting: the pose is odometry's, propagated from the last fit
};

const char* toString(LocalizationState state);

/// "x y z roll pitch yaw" (m, rad; rotation yaw * pitch * roll) as a pose; none unless six numbers.
std::optional<Pose> poseFromXyzRpy(const std::string& text);

struct LocalizationResult
{
  double stamp = 0.0;
  bool answered = false;  ///< a pose is known (false only while uninitialized)
  Pose pose;              ///< map <- sensor at the sweep end
  Pose correction;        ///< map <- odometry world
  LocalizationState state = LocalizationState::kUninitialized;
  MatchFitness fitness;    ///< of the sweep at `pose`
  MappingResult mapping;   ///< the registration's figures
  bool fits = false;       ///< the frame counted as fitting
  bool searched = false;   ///< a pose search ran for this frame
  int candidates = 0;      ///< poses scored by that search
  double search_ms = 0.0;  ///< its wall time
};

class Localizer
{
public:
  explicit Localizer(LocalizerConfig config = {});

  const LocalizerConfig& config() const { return config_; }
  /// Loads the map (replacing any other); the matching takes its cube and leaf sizes. State: uninitialized.
  void loadMap(const MapData& map);
  /// map <- sensor for the next frame; any time, in any state (a reset of the pose).
  void setInitialPose(const Pose& map_from_sensor);
  /// Localizes one odometry frame; the map does not change.
  LocalizationResult process(const OdometryFrame& frame);

  LocalizationState state() const { return state_; }
  const LaserMapping& mapping() const { return mapping_; }
  /// Candidate positions of the global search (from the map's trajectory or its ground).
  const std::vector<Eigen::Vector3d>& globalCandidates() const { return global_positions_; }
  /// Forgets the pose (the map stays): uninitialized.
  void reset();
  /// The odometry frames stopped continuing the previous ones (FrameAdmission's reset reason); applied at
  /// the next process(). The prior map stays either way; what must not cross the discontinuity is the
  /// correction (map <- odometry world), which belongs to the old odometry trajectory.
  /// - kOdometryRestarted: odometry's world began anew where the sensor was, while the sensor went on, so
  ///   the last pose still holds but the correction does not: it is re-derived from the last pose, and the
  ///   localizer searches around it and converges as from an initial pose (localizing); lost stays lost,
  ///   propagated from that pose. Before any pose there is nothing to carry over.
  /// - kJumpedBack: the data started over (a looping bag): the last pose says nothing about where the
  ///   sensor is now, so it is forgotten and the localizer starts again as it started the first time: from
  ///   the initial pose that applied to the first frame (the pose at the data's start, as ~initial_pose
  ///   gives it) when there was one, else uninitialized (the global search when enabled, else waiting for
  ///   an initial pose). An initial pose given since still applies instead.
  /// - kRequested: reset().
  void restart(ResetReason reason);

private:
  LocalizerConfig config_;
  LaserMapping mapping_;
  LocalizationState state_ = LocalizationState::kUninitialized;
  Pose correction_;
  bool initial_pending_ = false;
  Pose initial_pose_;
  bool search_pending_ = false;
  bool rebase_pending_ = false;     ///< restart(kOdometryRestarted): re-derive the correction at the next frame
  bool has_pose_ = false;           ///< last_pose_ holds the last answer
  Pose last_pose_;                  ///< map <- sensor of the last answer
  std::optional<Pose> start_pose_;  ///< the initial pose that applied to the first frame of the data
  std::size_t run_frames_ = 0;      ///< frames processed since the map was loaded or the data started over
  int good_frames_ = 0, bad_frames_ = 0, lost_frames_ = 0;
  double last_residual_ = 0.0, last_step_ = 0.0;
  int outer_iterations_ = 0;  ///< what mapping_'s configuration holds now
  std::vector<Eigen::Vector3d> global_positions_;

  using Scored = ScoredPose;
  void useOuterIterations(int outer);
  bool fits(const MatchFitness& f, bool localized) const;
  /// Registers `frame` from `start` (map <- sensor) and scores the result with the full fitness.
  Scored registerFrom(const OdometryFrame& frame, const Pose& start);
  /// The `keep` best of `starts` by the coarse score (every search_stride-th point, search_inlier_residual).
  std::vector<Scored> bestCoarse(const OdometryFrame& frame, const std::vector<Pose>& starts, int keep);
  /// Best pose among `starts` (coarse scores, the best `refine` registered); counts candidates.
  Scored searchAmong(const OdometryFrame& frame, const std::vector<Pose>& starts, int refine, int& candidates);
  /// poseGrid() around `centre` with the search steps.
  std::vector<Pose> gridAround(const Pose& centre, double radius, double yaw) const;
  std::vector<Pose> globalStarts() const;
  void setGlobalCandidates(const MapData& map);
};

}  // namespace aloam
