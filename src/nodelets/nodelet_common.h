// Small pieces shared by the nodelets.
#pragma once

#include <ros/duration.h>
#include <ros/time.h>

namespace aloam_nodelet
{
/// Seconds between repeats of a per-frame warning.
constexpr double kThrottleSeconds = 5.0;

/// Notices input that starts over (a looping bag): a stamp more than `tolerance` before the previous one.
class TimeJumpDetector
{
public:
  explicit TimeJumpDetector(double tolerance_seconds = 1.0) : tolerance_(tolerance_seconds) {}

  /// Records `stamp`; true when it jumped back. Sets `jump` to how far (seconds).
  bool jumpedBack(const ros::Time& stamp, double& jump)
  {
    const bool back = !last_.isZero() && stamp + tolerance_ < last_;
    jump = back ? (last_ - stamp).toSec() : 0.0;
    last_ = stamp;
    return back;
  }
  void reset() { last_ = ros::Time(); }

private:
  ros::Duration tolerance_;
  ros::Time last_;
};

}  // namespace aloam_nodelet
