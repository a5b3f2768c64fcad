// Small pieces shared by the nodelets.
#pragma once

#include <array>
#include <cstdint>
#include <cstdio>
#include <string>

#include <diagnostic_updater/DiagnosticStatusWrapper.h>
#include <ros/node_handle.h>
#include <ros/time.h>

#include "aloam_nodelet/core/pose_solver.h"
#include "aloam_nodelet/core/stamp_check.h"
#include "aloam_nodelet/ros/stage_messages.h"
#include "param_utils.h"

namespace aloam_nodelet
{
/// Seconds between repeats of a per-frame warning.
constexpr double kThrottleSeconds = 5.0;

/// True (after a throttled warning naming the defect) when a stage message must be dropped:
/// aloam::ros_io::validate() refuses it. From another process or a bag it may hold anything.
template <typename StageMessage>
bool malformed(const StageMessage& msg, const char* topic, const std::string& logger)
{
  const std::string error = aloam::ros_io::validate(msg);
  if (!error.empty())
  {
    ROS_WARN_STREAM_THROTTLE_NAMED(kThrottleSeconds, logger, "dropping a malformed " << topic << " message: " << error);
  }
  return !error.empty();
}

/// The time policy of a stage from its private parameters (read once at start-up): ~scan_period,
/// ~max_gap_sweeps, ~jump_back_tolerance.
inline aloam::StampCheckConfig stampCheckParams(const ros::NodeHandle& pnh, const std::string& logger)
{
  aloam::StampCheckConfig config;
  config.scan_period = boundedParam(pnh, logger, "scan_period", config.scan_period, 0.01, 1.0);
  config.max_gap_sweeps = boundedParam(pnh, logger, "max_gap_sweeps", config.max_gap_sweeps, 1.0, 1000.0);
  config.jump_back_tolerance =
      boundedParam(pnh, logger, "jump_back_tolerance", config.jump_back_tolerance, 0.0, 3600.0);
  return config;
}

/// Limits the warnings about unusual stamps to one per kThrottleSeconds for each verdict, per instance (two
/// pipelines in one manager do not silence each other).
class VerdictThrottle
{
public:
  /// True when a warning about `verdict` may be logged now (and then not again for kThrottleSeconds).
  bool due(aloam::StampVerdict verdict)
  {
    const ros::WallTime now = ros::WallTime::now();
    ros::WallTime& last = last_warning_[static_cast<std::size_t>(verdict)];
    if (!last.isZero() && (now - last).toSec() < kThrottleSeconds)
    {
      return false;
    }
    last = now;
    return true;
  }

private:
  std::array<ros::WallTime, 6> last_warning_{};  // indexed by StampVerdict
};

/// The warning for a sweep at `stamp` on `input` dropped with `verdict` (duplicate or out of order), `step`
/// seconds after the last one taken.
inline std::string dropMessage(aloam::StampVerdict verdict, const std::string& input, const ros::Time& stamp,
                               double step, const aloam::StampCounts& c)
{
  char text[256];
  if (verdict == aloam::StampVerdict::kDuplicate)
  {
    std::snprintf(text, sizeof(text), "%s: sweep stamped %.6f dropped: same stamp as the last one (%zu so far)",
                  input.c_str(), stamp.toSec(), c.duplicates);
  }
  else
  {
    std::snprintf(text, sizeof(text),
                  "%s: sweep stamped %.6f dropped: %.3f s older than the last one, out of order (%zu so far)",
                  input.c_str(), stamp.toSec(), -step, c.out_of_order);
  }
  return text;
}

/// Adds stamp counts to a diagnostics status.
inline void reportStamps(diagnostic_updater::DiagnosticStatusWrapper& s, const aloam::StampCounts& c)
{
  s.add("stamps duplicate (dropped)", c.duplicates);
  s.add("stamps out of order (dropped)", c.out_of_order);
  s.add("time gaps (motion prediction restarted)", c.gaps);
  s.add("time jumps back (reset)", c.jumps_back);
}

/// Checks the stamp of every input sweep of a stage (aloam::StampCheck; aloam::actionFor says what the stage
/// does with it) and throttles the warnings. Not thread-safe: the stage calls it under its own mutex.
class StampGuard
{
public:
  explicit StampGuard(const aloam::StampCheckConfig& config = {}) : check_(config) {}

  void setConfig(const aloam::StampCheckConfig& config) { check_.setConfig(config); }
  const aloam::StampCheckConfig& config() const { return check_.config(); }
  aloam::StampVerdict check(const ros::Time& stamp) { return check_.check(static_cast<std::int64_t>(stamp.toNSec())); }
  double lastStep() const { return check_.lastStep(); }
  const aloam::StampCounts& counts() const { return check_.counts(); }
  void reset() { check_.reset(); }
  bool warningDue(aloam::StampVerdict verdict) { return throttle_.due(verdict); }
  std::string dropMessage(aloam::StampVerdict verdict, const std::string& input, const ros::Time& stamp) const
  {
    return aloam_nodelet::dropMessage(verdict, input, stamp, check_.lastStep(), check_.counts());
  }
  void report(diagnostic_updater::DiagnosticStatusWrapper& s) const { reportStamps(s, check_.counts()); }

private:
  aloam::StampCheck check_;
  VerdictThrottle throttle_;
};

/// The match and degeneracy figures odometry and mapping both report for their last frame (one wording for
/// both stages, so tools and tests read them alike).
template <typename Frame>
void addMatchDiagnostics(diagnostic_updater::DiagnosticStatusWrapper& s, const Frame& last, std::size_t degraded,
                         std::size_t remapped)
{
  s.add("edge matches", last.corner_matches);
  s.add("plane matches", last.plane_matches);
  s.addf("constraint (degenerate below min)", "%.1f", last.constraint);
  s.add("degenerate directions", last.degenerate.size());
  s.add("degenerate (sensor frame)", aloam::describe(last.degenerate));
  s.add("degraded frames", degraded);
  s.add("remapped frames (partially degenerate)", remapped);
}

}  // namespace aloam_nodelet
