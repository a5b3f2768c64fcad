#include "aloam_nodelet/core/pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <stdexcept>

namespace aloam
{
namespace
{
using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start)
{
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// Odometry resolves its elevation window through the registration's beam table unless given one.
LaserOdometryConfig withBeamTable(const PipelineConfig& config)
{
  LaserOdometryConfig odometry = config.odometry;
  if (odometry.ring_elevations_deg.empty())
  {
    odometry.ring_elevations_deg = config.registration.sensor.elevationsDeg();
  }
  return odometry;
}

// As many threads as the stage that asks for the most (stages run one after another).
int pipelineThreads(const PipelineConfig& config)
{
  return std::max({ config.registration.threads, config.odometry.threads, config.mapping.threads, 1 });
}
}  // namespace

Pipeline::Pipeline(const PipelineConfig& config)
  : executor_(std::make_shared<Executor>(pipelineThreads(config)))
  , registration_(config.registration, executor_)
  , odometry_(withBeamTable(config), executor_)
  , mapping_(config.mapping, executor_)
  , stamps_(config.stamps)
  , loop_(config.loop_closure ? std::make_unique<LoopClosure>(config.loop) : nullptr)
{
}

void Pipeline::reset()
{
  odometry_.reset();
  mapping_.reset();
  stamps_.reset();
  if (loop_)
  {
    loop_->reset();
  }
}

std::vector<std::string> Pipeline::loadGraph(LoopGraph graph, const Pose& initial)
{
  if (!loop_)
  {
    throw std::logic_error("loop closure is off: a saved graph needs it");
  }
  if (!initial.isFinite())
  {
    throw std::invalid_argument("the initial pose is not finite");
  }
  std::vector<std::string> warnings = loop_->importGraph(std::move(graph));  // throws before changing anything
  odometry_.reset();
  stamps_.reset();
  mapping_.startIn(LaserMapping::buildMap(loop_->mapSweeps(), mapping_.config()), initial);
  return warnings;
}

bool Pipeline::track(const Cloud& cloud, double stamp, bool has_ring, bool has_time, PipelineOutput& out)
{
  out.stamp_verdict = stamps_.check(static_cast<std::int64_t>(std::llround(stamp * 1e9)));
  const StampAction action = actionFor(out.stamp_verdict);
  if (!action.process)
  {
    out.status = PipelineStatus::kDroppedStamp;
    return false;
  }
  if (action.reset)
  {
    odometry_.reset();
    mapping_.reset();
    if (loop_)
    {
      loop_->reset();
    }
  }
  if (action.restart_motion)
  {
    odometry_.resetMotionPrior();
  }
  auto start = Clock::now();
  auto features = std::make_shared<FeatureSet>();
  const bool usable = registration_.process(cloud, stamp, has_ring, has_time, *features);
  out.timings.registration_ms = msSince(start);
  out.features = features;
  if (!usable)
  {
    out.status = PipelineStatus::kRejectedInput;
    return false;
  }

  start = Clock::now();
  out.odometry = odometry_.track(features);
  out.timings.odometry_ms = msSince(start);
  return true;
}

PipelineOutput Pipeline::processOdometry(const Cloud& cloud, double stamp, bool has_ring, bool has_time)
{
  PipelineOutput out;
  if (track(cloud, stamp, has_ring, has_time, out))
  {
    const auto start = Clock::now();
    odometry_.indexLast();
    out.timings.update_ms = msSince(start);
    out.status = PipelineStatus::kOk;
  }
  return out;
}

PipelineOutput Pipeline::process(const Cloud& cloud, double stamp, bool has_ring, bool has_time)
{
  PipelineOutput out;
  if (!track(cloud, stamp, has_ring, has_time, out))
  {
    return out;
  }

  auto start = Clock::now();
  out.mapping = mapping_.registerFrame(out.odometry);
  out.timings.mapping_ms = msSince(start);

  // The work a node does after publishing the pose (see the nodelets).
  start = Clock::now();
  odometry_.indexLast();
  mapping_.updateMap(out.mapping);
  out.timings.update_ms = msSince(start);
  if (loop_ && !out.odometry.distorted)
  {
    start = Clock::now();
    out.loop = loop_->addFrame(out.mapping.stamp, out.mapping.pose, mapping_.registeredCorners(),
                               mapping_.registeredSurfs(), out.odometry.full.get());
    if (out.loop.optimized)
    {
      mapping_.rebuildMap(loop_->mapSweeps(), out.loop.correction);
      out.mapping.pose = out.loop.correction * out.mapping.pose;
      out.mapping.correction = mapping_.correction();
    }
    out.timings.loop_ms = msSince(start);
  }
  out.status = PipelineStatus::kOk;
  return out;
}

}  // namespace aloam
