// What to do with a sweep given its stamp and the stamps seen before: the time policy of the stages,
// kept free of ROS so that every case has a unit test.
#pragma once

#include <cstddef>
#include <cstdint>

namespace aloam
{
struct StampCheckConfig
{
  double scan_period = 0.1;  ///< nominal seconds between sweeps
  /// A step forward longer than this many sweep periods is a gap: the motion since the last sweep is
  /// unknown, so a motion prediction must not be extrapolated over it.
  double max_gap_sweeps = 5.0;
  /// A stamp further back than this (seconds) means the data starts over (a looping bag); a smaller step
  /// back is a late sweep, dropped.
  double jump_back_tolerance = 1.0;
};

enum class StampVerdict
{
  kFirst,       ///< first stamp (or first after a reset): take it
  kInSequence,  ///< take it
  kGap,         ///< take it, but restart the motion prediction: the previous sweep is too long ago
  kJumpedBack,  ///< far back: the data starts over; reset, then take it as the first of the new run
  kDuplicate,   ///< the stamp of the last sweep taken: drop it
  kOutOfOrder,  ///< a little before the last sweep taken: drop it
};

/// True for the verdicts whose sweep is processed (everything but duplicates and late sweeps).
inline bool isTaken(StampVerdict verdict)
{
  return verdict != StampVerdict::kDuplicate && verdict != StampVerdict::kOutOfOrder;
}

/// What a stage does with a sweep given its verdict: the one time policy of every stage, the nodelets and
/// aloam_offline alike. A stage without state over time (registration) only needs `process`.
struct StampAction
{
  bool process = true;          ///< false: drop the sweep (duplicate, late)
  bool reset = false;           ///< the data starts over: forget the trajectory (odometry) and the map (mapping)
  bool restart_motion = false;  ///< too long since the last sweep: do not extrapolate the motion over the gap
};

inline StampAction actionFor(StampVerdict verdict)
{
  StampAction action;
  action.process = isTaken(verdict);
  action.reset = verdict == StampVerdict::kJumpedBack;
  action.restart_motion = verdict == StampVerdict::kGap;
  return action;
}

/// Short name of a verdict for log messages ("duplicate", "gap", ...).
const char* toString(StampVerdict verdict);

/// How many stamps got each verdict since construction (a reset keeps the counts).
struct StampCounts
{
  std::size_t taken = 0;
  std::size_t duplicates = 0;
  std::size_t out_of_order = 0;
  std::size_t gaps = 0;
  std::size_t jumps_back = 0;
};

/// Classifies the stamps of consecutive sweeps. Stamps are integer nanoseconds, so a duplicate is an exact
/// match and not a floating point coincidence.
class StampCheck
{
public:
  explicit StampCheck(StampCheckConfig config = {}) : config_(config) {}

  const StampCheckConfig& config() const { return config_; }
  void setConfig(const StampCheckConfig& config) { config_ = config; }

  /// Classifies `stamp_ns` against the last stamp taken and, if the sweep is taken, remembers it.
  StampVerdict check(std::int64_t stamp_ns);

  /// Seconds from the last stamp taken to the one just checked (negative: back; 0 for the first).
  double lastStep() const { return last_step_; }
  const StampCounts& counts() const { return counts_; }
  /// Forgets the last stamp: the next one is a first stamp.
  void reset() { has_last_ = false; }

private:
  StampCheckConfig config_;
  bool has_last_ = false;
  std::int64_t last_ns_ = 0;
  double last_step_ = 0.0;
  StampCounts counts_;
};

/// Why a stage starts over (forgets its map or its pose) before the next frame.
enum class ResetReason
{
  kNone,
  kJumpedBack,         ///< the stamps started over (a looping bag)
  kOdometryRestarted,  ///< odometry began a new trajectory at identity while the stamps went on
  kRequested,          ///< asked for (a reset service)
};

/// Short name of a reason for log messages ("jumped back", ...).
const char* toString(ResetReason reason);

struct OdometryFrame;

/// What the time policy made of an odometry frame (FrameAdmission::admit).
struct StampAdmission
{
  StampVerdict verdict = StampVerdict::kFirst;
  double step = 0.0;                       ///< seconds since the last stamp taken
  bool taken = false;                      ///< false: dropped (duplicate or late stamp)
  ResetReason reset = ResetReason::kNone;  ///< the frames stopped continuing the previous ones
};

/// The time policy of the stages that consume odometry frames (mapping, localization): the stamp check
/// plus the detection of an odometry restart, so that both stages see the same discontinuities. What a
/// stage does about them is its own (mapping starts a new map, localization keeps its prior map).
/// Not thread-safe.
class FrameAdmission
{
public:
  explicit FrameAdmission(StampCheckConfig config = {}) : stamps_(config) {}

  /// Classifies the frame stamped `stamp_ns`. A frame that is taken while an odometry trajectory is running
  /// and is the first of a new one (status kInitialized: odometry's reset service, a reload, a restarted
  /// manager) is an odometry restart; a jump back takes precedence (odometry restarts on it too).
  StampAdmission admit(const OdometryFrame& frame, std::int64_t stamp_ns);

  const StampCheckConfig& config() const { return stamps_.config(); }
  void setConfig(const StampCheckConfig& config) { stamps_.setConfig(config); }
  const StampCounts& counts() const { return stamps_.counts(); }
  std::size_t odometryRestarts() const { return odometry_restarts_; }

private:
  StampCheck stamps_;
  bool odometry_running_ = false;  // a frame of the current odometry trajectory was taken
  std::size_t odometry_restarts_ = 0;
};

}  // namespace aloam
