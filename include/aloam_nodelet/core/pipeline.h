// Registration, odometry and mapping composed for in-process use (offline runner, tests, benchmarks).
#pragma once

#include <memory>

#include "aloam_nodelet/core/laser_mapping.h"
#include "aloam_nodelet/core/laser_odometry.h"
#include "aloam_nodelet/core/loop_closure.h"
#include "aloam_nodelet/core/scan_registration.h"
#include "aloam_nodelet/core/stamp_check.h"

namespace aloam
{
struct PipelineConfig
{
  ScanRegistrationConfig registration;
  LaserOdometryConfig odometry;
  LaserMappingConfig mapping;
  StampCheckConfig stamps;  ///< the time policy the nodelets apply (aloam::actionFor)
  /// Loop closure after each map update (LoopClosure); off: the pipeline is the three LOAM stages alone.
  bool loop_closure = false;
  LoopClosureConfig loop;
};

enum class PipelineStatus
{
  kOk,
  kRejectedInput,  ///< too few usable points: nothing changed, no pose for this sweep
  kDroppedStamp,   ///< duplicate or late stamp: dropped before any work, as the nodelets drop it
};

/// Wall time of each step. The first three lie on the latency path (input to mapped pose); the update
/// (indexing the sweep for the next odometry, adding it to the map, indexing the submap) comes after
/// the pose is out.
struct PipelineTimings
{
  double registration_ms = 0.0;
  double odometry_ms = 0.0;
  double mapping_ms = 0.0;
  double update_ms = 0.0;
  double loop_ms = 0.0;  ///< loop closure: keyframe, verification, graph and map rebuild (after the pose)

  double latencyPathMs() const { return registration_ms + odometry_ms + mapping_ms; }
  double totalMs() const { return latencyPathMs() + update_ms + loop_ms; }
};

struct PipelineOutput
{
  PipelineStatus status = PipelineStatus::kRejectedInput;
  StampVerdict stamp_verdict = StampVerdict::kFirst;
  std::shared_ptr<const FeatureSet> features;
  OdometryFrame odometry;
  MappingResult mapping;  ///< its pose is moved into the corrected map when a loop closed on this frame
  LoopUpdate loop;
  PipelineTimings timings;
};

/// The three LOAM stages run one after another on each sweep, sharing one Executor (its threads are
/// joined when the pipeline is destroyed). Holds no global state: any number of pipelines may live in one
/// process.
class Pipeline
{
public:
  explicit Pipeline(const PipelineConfig& config = {});

  /// Runs one sweep through all stages. `has_ring` / `has_time`: whether those point fields are filled.
  /// The stamp goes through the nodelets' time policy first: dropped when duplicate or late, a reset when
  /// it jumps back, the motion prediction restarted after a gap.
  PipelineOutput process(const Cloud& cloud, double stamp, bool has_ring, bool has_time);
  /// Registration and odometry only, under the same time policy (localization runs its own matching
  /// against a saved map); `mapping` of the output stays empty.
  PipelineOutput processOdometry(const Cloud& cloud, double stamp, bool has_ring, bool has_time);

  void reset();
  /// Continues a saved graph (needs PipelineConfig::loop_closure): as MappingSession::loadGraph, with
  /// `initial` the saved map's pose of the next sweep's sensor (map <- odometry world). Registration and
  /// odometry start over. Returns what was adapted; throws std::logic_error without loop closure and
  /// std::invalid_argument for an inconsistent graph. A later reset (a jump back in time) forgets it.
  std::vector<std::string> loadGraph(LoopGraph graph, const Pose& initial);
  const ScanRegistration& registration() const { return registration_; }
  const LaserOdometry& odometry() const { return odometry_; }
  const LaserMapping& mapping() const { return mapping_; }
  /// Null unless PipelineConfig::loop_closure.
  const LoopClosure* loopClosure() const { return loop_.get(); }
  const std::shared_ptr<Executor>& executor() const { return executor_; }

private:
  std::shared_ptr<Executor> executor_;  // first: the stages use it
  ScanRegistration registration_;
  LaserOdometry odometry_;
  LaserMapping mapping_;
  StampCheck stamps_;
  std::unique_ptr<LoopClosure> loop_;

  /// The time policy, registration and odometry's track(); false if the sweep was dropped or rejected.
  bool track(const Cloud& cloud, double stamp, bool has_ring, bool has_time, PipelineOutput& out);
};

}  // namespace aloam
