#include "aloam_nodelet/core/stamp_check.h"

#include "aloam_nodelet/core/laser_odometry.h"

namespace aloam
{
namespace
{
constexpr double kNanosecondsPerSecond = 1e9;
}  // namespace

const char* toString(StampVerdict verdict)
{
  switch (verdict)
  {
    case StampVerdict::kFirst:
      return "first";
    case StampVerdict::kInSequence:
      return "in sequence";
    case StampVerdict::kGap:
      return "gap";
    case StampVerdict::kJumpedBack:
      return "jumped back";
    case StampVerdict::kDuplicate:
      return "duplicate";
    case StampVerdict::kOutOfOrder:
      return "out of order";
  }
  return "unknown";
}

StampVerdict StampCheck::check(std::int64_t stamp_ns)
{
  StampVerdict verdict = StampVerdict::kFirst;
  last_step_ = 0.0;
  if (has_last_)
  {
    last_step_ = static_cast<double>(stamp_ns - last_ns_) / kNanosecondsPerSecond;
    if (stamp_ns == last_ns_)
    {
      verdict = StampVerdict::kDuplicate;
    }
    else if (last_step_ < -config_.jump_back_tolerance)
    {
      verdict = StampVerdict::kJumpedBack;
    }
    else if (last_step_ < 0.0)
    {
      verdict = StampVerdict::kOutOfOrder;
    }
    else if (last_step_ > config_.max_gap_sweeps * config_.scan_period)
    {
      verdict = StampVerdict::kGap;
    }
    else
    {
      verdict = StampVerdict::kInSequence;
    }
  }

  switch (verdict)
  {
    case StampVerdict::kDuplicate:
      ++counts_.duplicates;
      return verdict;  // the last stamp stays: a late sweep must not move the clock back
    case StampVerdict::kOutOfOrder:
      ++counts_.out_of_order;
      return verdict;
    case StampVerdict::kGap:
      ++counts_.gaps;
      break;
    case StampVerdict::kJumpedBack:
      ++counts_.jumps_back;
      break;
    default:
      break;
  }
  ++counts_.taken;
  has_last_ = true;
  last_ns_ = stamp_ns;
  return verdict;
}

const char* toString(ResetReason reason)
{
  switch (reason)
  {
    case ResetReason::kNone:
      return "none";
    case ResetReason::kJumpedBack:
      return "jumped back";
    case ResetReason::kOdometryRestarted:
      return "odometry restarted";
    case ResetReason::kRequested:
      return "requested";
  }
  return "unknown";
}

StampAdmission FrameAdmission::admit(const OdometryFrame& frame, std::int64_t stamp_ns)
{
  StampAdmission out;
  out.verdict = stamps_.check(stamp_ns);
  out.step = stamps_.lastStep();
  const StampAction action = actionFor(out.verdict);
  out.taken = action.process;
  if (!out.taken)
  {
    return out;
  }
  if (action.reset)
  {
    out.reset = ResetReason::kJumpedBack;
  }
  else if (frame.status == OdometryStatus::kInitialized && odometry_running_)
  {
    ++odometry_restarts_;
    out.reset = ResetReason::kOdometryRestarted;
  }
  odometry_running_ = true;
  return out;
}

}  // namespace aloam
