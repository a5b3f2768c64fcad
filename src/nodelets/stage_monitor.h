// Per-frame timing and rate of a nodelet stage, published through diagnostic_updater together with the
// stage's own figures.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/node_handle.h>

namespace aloam_nodelet
{
class StageMonitor
{
public:
  using Report = std::function<void(diagnostic_updater::DiagnosticStatusWrapper&)>;

  /// `report` adds the stage's own key-values and may raise the level. Diagnostics go out after frames
  /// and, without frames, once per updater period from a timer on `nh`'s callback queue.
  void init(ros::NodeHandle& nh, const ros::NodeHandle& pnh, const std::string& name, Report report)
  {
    report_ = std::move(report);
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, name);
    updater_->setHardwareID("aloam_nodelet");
    updater_->add(name, [this](diagnostic_updater::DiagnosticStatusWrapper& s) { produce(s); });
    timer_ = nh.createTimer(ros::Duration(updater_->getPeriod()), [this](const ros::TimerEvent&) { update(); });
  }

  /// Records one processed frame that took `milliseconds`, then lets the updater publish if it is due.
  void frameDone(double milliseconds)
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const auto now = std::chrono::steady_clock::now();
      if (frames_ > 0)
      {
        const double interval = std::chrono::duration<double>(now - last_frame_).count();
        rate_hz_ = interval > 0.0 ? (rate_hz_ > 0.0 ? 0.9 * rate_hz_ + 0.1 / interval : 1.0 / interval) : rate_hz_;
      }
      last_frame_ = now;
      ++frames_;
      last_ms_ = milliseconds;
      max_ms_ = std::max(max_ms_, milliseconds);
      mean_ms_ += (milliseconds - mean_ms_) / static_cast<double>(frames_);
    }
    update();
  }

private:
  // diagnostic_updater::Updater::update() reads and writes its next publishing time without a lock, and a
  // stage calls it from two threads: the timer's callback and the thread that processed the frame (the
  // mapping worker is not the nodelet's callback thread).
  void update()
  {
    std::lock_guard<std::mutex> lock(update_mutex_);
    if (updater_)
    {
      updater_->update();
    }
  }

  void produce(diagnostic_updater::DiagnosticStatusWrapper& s)
  {
    s.summary(diagnostic_msgs::DiagnosticStatus::OK, "ok");
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (frames_ == 0)
      {
        s.summary(diagnostic_msgs::DiagnosticStatus::WARN, "no frame processed yet");
      }
      s.add("frames", frames_);
      s.addf("rate (Hz)", "%.2f", rate_hz_);
      s.addf("last frame (ms)", "%.1f", last_ms_);
      s.addf("mean frame (ms)", "%.1f", mean_ms_);
      s.addf("max frame (ms)", "%.1f", max_ms_);
    }
    if (report_)
    {
      report_(s);
    }
  }

  std::mutex update_mutex_;  // taken before the updater's own lock and mutex_ (produce runs inside update)
  std::mutex mutex_;
  std::size_t frames_ = 0;
  double last_ms_ = 0.0, mean_ms_ = 0.0, max_ms_ = 0.0, rate_hz_ = 0.0;
  std::chrono::steady_clock::time_point last_frame_;
  Report report_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::Timer timer_;
};

/// Milliseconds since `start`.
inline double msSince(std::chrono::steady_clock::time_point start)
{
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace aloam_nodelet
