// aloam_offline: runs the LOAM pipeline over a KITTI sequence folder or a rosbag, frame by frame, and
// writes the mapped trajectory, the map and per-stage timings; or localizes the sweeps in a saved map.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <unistd.h>

#include <pcl/io/pcd_io.h>
#include <pcl/io/impl/pcd_io.hpp>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include "aloam_nodelet/core/graph_file.h"
#include "aloam_nodelet/core/localizer.h"
#include "aloam_nodelet/core/map_file.h"
#include "aloam_nodelet/core/pipeline.h"
#include "aloam_nodelet/eval/timing_stats.h"
#include "aloam_nodelet/eval/trajectory_io.h"
#include "aloam_nodelet/io/kitti_dataset.h"
#include "aloam_nodelet/ros/pointcloud2_reader.h"

namespace fs = std::filesystem;

namespace
{
constexpr const char* kUsage =
    "usage: aloam_offline (--kitti DIR | --bag FILE --topic TOPIC) --sensor PRESET --trajectory OUT.txt\n"
    "                     [--tum OUT.tum] [--map OUT.pcd] [--deskew] [--minimum-range M] [--max-frames N]\n"
    "                     [--keep-every N] [--baseline] [--odometry-trajectory OUT.txt]\n"
    "                     [--nearby-elevation-deg DEG] [--save-map OUT.pcd] [--start-frame N]\n"
    "                     [--loop-closure] [--loops OUT.tsv] [--min-loop-separation S] [--keyframe-distance M]\n"
    "                     [--save-graph OUT.graph] [--load-graph GRAPH [--initial-pose \"x y z roll pitch yaw\"]]\n"
    "       aloam_offline (--kitti DIR | --bag FILE --topic TOPIC) --sensor PRESET --trajectory OUT.txt\n"
    "                     --localize MAP.pcd [--initial-pose \"x y z roll pitch yaw\"] [--global]\n"
    "                     [--localization-log OUT.txt] [--map-after OUT.pcd] [--start-frame N]\n"
    "\n"
    "  --kitti DIR        KITTI odometry sequence folder: DIR/velodyne/*.bin (+ DIR/times.txt)\n"
    "  --bag FILE         rosbag with sensor_msgs/PointCloud2 on --topic\n"
    "  --sensor PRESET    VLP16 | HDL32 | HDL64 | VLP32C | OS1_64 | OS0_64 | OS1_128\n"
    "  --trajectory OUT   mapped lidar pose of every frame relative to the first, KITTI 3x4 rows\n"
    "  --tum OUT          the same poses in TUM format (stamp tx ty tz qx qy qz qw)\n"
    "  --map OUT.pcd      the feature map at the end (binary PCD, x y z intensity time ring)\n"
    "  --save-map OUT.pcd the map for localization: PCD of x y z label (1 edge, 2 plane) + OUT.pcd.yaml\n"
    "  --start-frame N    begin at frame N (odometry starts there)\n"
    "  --loop-closure     close loops (keyframes, place search, verification, pose graph): --trajectory,\n"
    "                     --map and --save-map then hold the corrected result\n"
    "  --loops OUT.tsv    every loop tried: keyframes, stamps, source, accepted, reason, fitness, correction\n"
    "  --save-graph OUT.graph\n"
    "                     the pose graph at the end (keyframes with clouds and descriptors, edges), for\n"
    "                     --load-graph in a later run (needs --loop-closure)\n"
    "  --load-graph GRAPH continue a saved graph (needs --loop-closure): the map starts as its keyframes, this\n"
    "                     run's keyframes join the graph, and --trajectory is in the graph's map frame (where\n"
    "                     the saved run started), no longer relative to this run's first frame; the first\n"
    "                     frame is at --initial-pose in that frame (default: the identity, the saved start)\n"
    "  --min-loop-separation S\n"
    "                     no loop between keyframes closer than S seconds or S metres of path (default 30)\n"
    "  --keyframe-distance M\n"
    "                     a loop-closure keyframe every M metres of path (default 1)\n"
    "  --localize MAP.pcd localize every sweep in MAP (never changed) instead of mapping; --trajectory then\n"
    "                     holds the map <- lidar pose of every frame from --start-frame (the last known one\n"
    "                     while no pose is known)\n"
    "  --initial-pose \"x y z roll pitch yaw\"\n"
    "                     map <- lidar at the first frame (m, rad; yaw * pitch * roll), with --localize or\n"
    "                     --load-graph\n"
    "  --global           no initial pose: search the whole map for it (global localization)\n"
    "  --localization-log OUT\n"
    "                     per frame: frame stamp answered state inlier_share mean_residual matched tried\n"
    "                     fits searched candidates search_ms localize_ms x y z roll pitch yaw\n"
    "  --map-after OUT.pcd the localizer's map after the run, as --save-map writes it\n"
    "  --odometry-trajectory OUT\n"
    "                     odometry's pose of every frame (before mapping's correction), KITTI 3x4 rows\n"
    "  --deskew           correct motion within each sweep (KITTI scans are already corrected: off)\n"
    "  --minimum-range M  drop returns closer than M metres (default: 5 for --kitti, 0.3 otherwise)\n"
    "  --kitti-vertical-correction DEG\n"
    "                     raise KITTI elevations by DEG (default 0.205, KITTI's known intrinsic error; 0: off)\n"
    "  --corner-leaf M, --surf-leaf M\n"
    "                     laser_mapping's corner_leaf_size and surf_leaf_size (default 0.4 and 0.8)\n"
    "  --leaf-min-scale S laser_mapping's leaf_min_scale: leaves shrink in confined scenes down to S times\n"
    "                     the configured ones (default 0.25; 1: fixed leaves)\n"
    "  --max-frames N     stop after N frames\n"
    "  --keep-every N     use only every Nth sweep (0, N, 2N, ...) with its real stamp, as behind a throttle\n"
    "  --baseline         the handling of degeneracy and time of commit 81f6493 (A-LOAM-like): a weak direction\n"
    "                     keeps the whole prediction, and the last motion is the prediction and the deskew\n"
    "                     motion whatever the time between stamps, and odometry's ring neighbourhood counts\n"
    "                     rings (nearby_scan) instead of degrees, mapping's leaves stay as configured, and\n"
    "                     every sweep has one pose (no sweep_span)\n"
    "  --nearby-elevation-deg DEG\n"
    "                     odometry's ring neighbourhood in degrees of elevation (0: nearby_scan rings)\n"
    "  --reject-occluded on|off\n"
    "                     scan_registration's reject_occluded (default: on, off for --kitti)\n"
    "  --occlusion-continuity X\n"
    "                     scan_registration's occlusion_continuity: a gap that a surface runs on across\n"
    "                     (within X times the gap) is no occlusion (default 0.15; 0: every gap, as LOAM)\n"
    "  --occlusion-straight M\n"
    "                     scan_registration's occlusion_straight_tolerance: the far side of such a gap\n"
    "                     gives no edges where it lies on one line with the near side, within M metres\n"
    "                     (default 0.05; 0: it may)\n"
    "  --curvature-across-ring on|off\n"
    "                     scan_registration's curvature_across_ring: mapping's edges need curvature\n"
    "                     across the ring, not uneven spacing along it; odometry keeps LOAM's edges\n"
    "                     (default on; off: LOAM's edges for both)\n"
    "  --no-motion-hypotheses\n"
    "                     odometry never tries other starts after a poor solve (laser_odometry's\n"
    "                     motion_hypotheses: false)\n"
    "  --sweep-span on|off laser_mapping's sweep_span (default on): a sweep in which the motion changed gets\n"
    "                     a start and an end pose\n"
    "  --span-start-weight W\n"
    "                     laser_mapping's span_start_weight (default 3)\n"
    "  --hard-remap       odometry and mapping keep the prediction entirely along weak directions\n"
    "                     (laser_odometry's and laser_mapping's soft_remap: false)\n"
    "  --odometry-min-constraint X, --mapping-min-constraint X\n"
    "                     the stages' min_constraint (directions weaker than X are degenerate)\n";

// Spacing of the mapped positions a saved map's sidecar keeps (m): candidates for global localization.
constexpr double kTrajectorySpacing = 1.0;

struct Options
{
  std::string kitti_dir, bag_file, topic, sensor, trajectory, tum, map, odometry_trajectory;
  std::string save_map, localize, initial_pose, localization_log, map_after, loops, save_graph, load_graph;
  bool loop_closure = false;
  std::optional<double> min_loop_separation, keyframe_distance;
  bool global = false;
  std::size_t start_frame = 0;
  bool deskew = false;
  bool baseline = false;
  bool motion_hypotheses = true;
  bool soft_remap = true;
  std::optional<bool> reject_occluded, sweep_span, curvature_across_ring;
  std::optional<double> span_start_weight;
  std::optional<double> occlusion_continuity, occlusion_straight;
  std::size_t keep_every = 1;
  std::optional<double> odometry_min_constraint, mapping_min_constraint, nearby_elevation_deg;
  std::optional<double> minimum_range, corner_leaf, surf_leaf, leaf_min_scale;
  double kitti_vertical_correction = aloam::io::kKittiVerticalCorrectionDeg;
  std::size_t max_frames = 0;
};

/// One input sweep.
struct Frame
{
  aloam::Cloud cloud;
  double stamp = 0.0;
  bool has_ring = false;
  bool has_time = false;
};

/// Where sweeps come from.
class FrameSource
{
public:
  virtual ~FrameSource() = default;
  virtual std::size_t size() const = 0;
  /// Frame i's stamp without reading it (the stamp read() gives it).
  virtual double stamp(std::size_t i) const = 0;
  /// Reads frame i; false (with a message on stderr) if it cannot be used.
  virtual bool read(std::size_t i, Frame& frame) = 0;
};

class KittiSource : public FrameSource
{
public:
  KittiSource(const fs::path& dir, double vertical_correction_deg)
    : files_(aloam::io::listKittiScans(dir.string())), vertical_correction_deg_(vertical_correction_deg)
  {
    const fs::path times = dir / "times.txt";
    if (fs::exists(times))
    {
      stamps_ = aloam::eval::readTimes(times.string());
      if (stamps_.size() < files_.size())
      {
        std::cerr << "warning: times.txt has " << stamps_.size() << " lines for " << files_.size()
                  << " scans; the rest are stamped at 10 Hz\n";
      }
    }
  }

  std::size_t size() const override { return files_.size(); }
  double stamp(std::size_t i) const override
  {
    return i < stamps_.size() ? stamps_[i] : kKittiPeriod * static_cast<double>(i);
  }

  bool read(std::size_t i, Frame& frame) override
  {
    try
    {
      aloam::io::readKittiScan(files_[i], frame.cloud);
    }
    catch (const std::exception& e)
    {
      std::cerr << "\n" << e.what() << "\n";
      return false;
    }
    if (vertical_correction_deg_ != 0.0)
    {
      aloam::io::correctVerticalAngle(frame.cloud, vertical_correction_deg_);
    }
    frame.stamp = stamp(i);
    frame.has_ring = false;
    frame.has_time = false;
    return true;
  }

private:
  static constexpr double kKittiPeriod = 0.1;
  std::vector<std::string> files_;
  std::vector<double> stamps_;
  double vertical_correction_deg_;
};

class BagSource : public FrameSource
{
public:
  /// Every `keep_every`th message of `topic`, in bag order; stamps are the messages' header stamps.
  BagSource(const std::string& file, const std::string& topic, double scan_period, std::size_t keep_every)
  {
    options_.scan_period = scan_period;
    bag_.open(file, rosbag::bagmode::Read);
    rosbag::View view(bag_, rosbag::TopicQuery(topic));
    std::size_t index = 0;
    for (const rosbag::MessageInstance& m : view)
    {
      auto msg = m.instantiate<sensor_msgs::PointCloud2>();
      if (msg && index++ % keep_every == 0)
      {
        messages_.push_back(msg);
      }
    }
    if (messages_.empty())
    {
      throw std::runtime_error("no sensor_msgs/PointCloud2 on topic " + topic + " in " + file);
    }
  }

  std::size_t size() const override { return messages_.size(); }
  double stamp(std::size_t i) const override { return messages_[i]->header.stamp.toSec(); }

  bool read(std::size_t i, Frame& frame) override
  {
    const auto report = aloam::ros_io::readPointCloud2(*messages_[i], options_, frame.cloud);
    if (!report.ok)
    {
      std::cerr << "\nmessage " << i << " skipped: " << report.error << "\n";
      return false;
    }
    frame.stamp = messages_[i]->header.stamp.toSec();
    frame.has_ring = report.has_ring;
    frame.has_time = report.has_time;
    return true;
  }

private:
  rosbag::Bag bag_;
  std::vector<sensor_msgs::PointCloud2::ConstPtr> messages_;
  aloam::ros_io::ReaderOptions options_;
};

double msSince(std::chrono::steady_clock::time_point start)
{
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

/// Mean, median and 90th percentile of a series of milliseconds.
std::string summary(const std::vector<double>& ms)
{
  return aloam::eval::formatMs(aloam::eval::summarize(ms));
}

void showProgress(std::size_t done, std::size_t total, double seconds, bool tty)
{
  const std::size_t step = std::max<std::size_t>(1, total / 10);
  if (!tty && done != total && done % step != 0)
  {
    return;
  }
  constexpr int kWidth = 30;
  const int filled = static_cast<int>(kWidth * done / std::max<std::size_t>(total, 1));
  std::fprintf(stderr, "%s[%s%s] %zu/%zu frames  %.1f frames/s%s", tty ? "\r" : "", std::string(filled, '#').c_str(),
               std::string(kWidth - filled, ' ').c_str(), done, total, seconds > 0 ? done / seconds : 0.0,
               tty ? "" : "\n");
  if (tty && done == total)
  {
    std::fputc('\n', stderr);
  }
}

int localize(const Options& opt, const aloam::PipelineConfig& config, FrameSource& source, std::size_t end);

/// The settings a saved graph records (and a loaded one is compared with).
aloam::GraphFileInfo graphInfo(const Options& opt, const aloam::PipelineConfig& config)
{
  aloam::GraphFileInfo info;
  info.sensor = opt.sensor;
  info.cube_size = config.mapping.cube_size;
  info.corner_leaf_size = config.mapping.corner_leaf_size;
  info.surf_leaf_size = config.mapping.surf_leaf_size;
  return info;
}

/// One row per loop tried: target and current keyframe, their stamps, how it was found, the verdict and
/// its figures.
void writeLoops(const std::string& path, const aloam::LoopClosure& loops, const FrameSource& source)
{
  // The input frame of a keyframe's stamp (frames are in stamp order). A loaded keyframe's stamp is looked
  // up in this input too: its frame is right when the saved run read the same input.
  const auto frameOf = [&](double stamp)
  {
    std::size_t lo = 0, hi = source.size();
    while (lo < hi)
    {
      const std::size_t mid = (lo + hi) / 2;
      if (source.stamp(mid) < stamp - 1e-6)
      {
        lo = mid + 1;
      }
      else
      {
        hi = mid;
      }
    }
    return lo;
  };
  const auto& keyframes = loops.keyframes();
  std::ofstream out(path);
  if (!out)
  {
    throw std::runtime_error("cannot write " + path);
  }
  out << "from\tto\tfrom_frame\tto_frame\tfrom_stamp\tto_stamp\tsource\taccepted\tinlier_share\tmean_residual_m\t"
         "descriptor_distance\tcorrection_m\tcorrection_deg\trel_x\trel_y\trel_z\trel_qx\trel_qy\trel_qz\trel_qw\t"
         "from_session\tto_session\treason\n";
  out << std::fixed;
  for (const aloam::LoopRecord& r : loops.history())
  {
    out << r.from << "\t" << r.to << "\t" << frameOf(r.from_stamp) << "\t" << frameOf(r.to_stamp) << "\t"
        << std::setprecision(6) << r.from_stamp << "\t" << r.to_stamp << "\t"
        << (r.source == aloam::LoopSource::kSessionStart ? "session_start" : aloam::toString(r.source)) << "\t"
        << (r.accepted ? 1 : 0) << "\t" << std::setprecision(3) << r.fitness.inlier_share << "\t"
        << r.fitness.mean_residual << "\t" << r.descriptor_distance << "\t" << r.correction_m << "\t"
        << r.correction_rad * 180.0 / M_PI << "\t" << std::setprecision(6) << r.relative.t.x() << "\t"
        << r.relative.t.y() << "\t" << r.relative.t.z() << "\t" << r.relative.q.x() << "\t" << r.relative.q.y() << "\t"
        << r.relative.q.z() << "\t" << r.relative.q.w() << "\t" << keyframes[r.from].session << "\t"
        << keyframes[r.to].session << "\t"
        << (!r.accepted      ? r.reason
            : r.weak.empty() ? "accepted"
                             : "accepted, weak along " + aloam::describe(r.weak))
        << "\n";
  }
}

bool parse(int argc, char** argv, Options& o)
{
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    auto value = [&](std::string& out)
    {
      if (i + 1 >= argc)
      {
        throw std::invalid_argument(arg + " needs a value");
      }
      out = argv[++i];
    };
    // A real (double or optional double) or a count (std::size_t) option.
    auto real = [&](auto& out)
    {
      std::string number;
      value(number);
      out = std::stod(number);
    };
    auto count = [&](std::size_t& out)
    {
      std::string number;
      value(number);
      out = static_cast<std::size_t>(std::stoul(number));
    };
    auto onOff = [&](std::optional<bool>& out)
    {
      std::string word;
      value(word);
      if (word != "on" && word != "off")
      {
        throw std::invalid_argument(arg + " takes on or off");
      }
      out = word == "on";
    };
    if (arg == "--kitti")
      value(o.kitti_dir);
    else if (arg == "--bag")
      value(o.bag_file);
    else if (arg == "--topic")
      value(o.topic);
    else if (arg == "--sensor")
      value(o.sensor);
    else if (arg == "--trajectory")
      value(o.trajectory);
    else if (arg == "--tum")
      value(o.tum);
    else if (arg == "--map")
      value(o.map);
    else if (arg == "--odometry-trajectory")
      value(o.odometry_trajectory);
    else if (arg == "--save-map")
      value(o.save_map);
    else if (arg == "--localize")
      value(o.localize);
    else if (arg == "--initial-pose")
      value(o.initial_pose);
    else if (arg == "--localization-log")
      value(o.localization_log);
    else if (arg == "--map-after")
      value(o.map_after);
    else if (arg == "--global")
      o.global = true;
    else if (arg == "--start-frame")
      count(o.start_frame);
    else if (arg == "--deskew")
      o.deskew = true;
    else if (arg == "--loop-closure")
      o.loop_closure = true;
    else if (arg == "--loops")
      value(o.loops);
    else if (arg == "--save-graph")
      value(o.save_graph);
    else if (arg == "--load-graph")
      value(o.load_graph);
    else if (arg == "--min-loop-separation")
      real(o.min_loop_separation);
    else if (arg == "--keyframe-distance")
      real(o.keyframe_distance);
    else if (arg == "--baseline")
      o.baseline = true;
    else if (arg == "--no-motion-hypotheses")
      o.motion_hypotheses = false;
    else if (arg == "--hard-remap")
      o.soft_remap = false;
    else if (arg == "--reject-occluded")
      onOff(o.reject_occluded);
    else if (arg == "--sweep-span")
      onOff(o.sweep_span);
    else if (arg == "--span-start-weight")
      real(o.span_start_weight);
    else if (arg == "--occlusion-continuity")
      real(o.occlusion_continuity);
    else if (arg == "--occlusion-straight")
      real(o.occlusion_straight);
    else if (arg == "--curvature-across-ring")
      onOff(o.curvature_across_ring);
    else if (arg == "--odometry-min-constraint")
      real(o.odometry_min_constraint);
    else if (arg == "--mapping-min-constraint")
      real(o.mapping_min_constraint);
    else if (arg == "--nearby-elevation-deg")
      real(o.nearby_elevation_deg);
    else if (arg == "--keep-every")
    {
      count(o.keep_every);
      if (o.keep_every == 0)
      {
        throw std::invalid_argument("--keep-every needs N >= 1");
      }
    }
    else if (arg == "--minimum-range")
      real(o.minimum_range);
    else if (arg == "--corner-leaf")
      real(o.corner_leaf);
    else if (arg == "--surf-leaf")
      real(o.surf_leaf);
    else if (arg == "--leaf-min-scale")
      real(o.leaf_min_scale);
    else if (arg == "--kitti-vertical-correction")
      real(o.kitti_vertical_correction);
    else if (arg == "--max-frames")
      count(o.max_frames);
    else if (arg == "--help" || arg == "-h")
    {
      std::cout << kUsage;
      std::exit(0);
    }
    else
    {
      throw std::invalid_argument("unknown argument " + arg);
    }
  }
  if (o.kitti_dir.empty() == o.bag_file.empty())
  {
    throw std::invalid_argument("give exactly one of --kitti and --bag");
  }
  if (!o.bag_file.empty() && o.topic.empty())
  {
    throw std::invalid_argument("--bag needs --topic");
  }
  if (o.sensor.empty() || o.trajectory.empty())
  {
    throw std::invalid_argument("--sensor and --trajectory are required");
  }
  if (o.localize.empty() && (o.global || !o.localization_log.empty() || !o.map_after.empty()))
  {
    throw std::invalid_argument("--global, --localization-log and --map-after need --localize");
  }
  if (o.localize.empty() && o.load_graph.empty() && !o.initial_pose.empty())
  {
    throw std::invalid_argument("--initial-pose needs --localize or --load-graph");
  }
  if (!o.localize.empty() && (!o.map.empty() || !o.save_map.empty()))
  {
    throw std::invalid_argument("--localize does not map: no --map or --save-map");
  }
  if (!o.loop_closure && (!o.loops.empty() || o.min_loop_separation || o.keyframe_distance || !o.save_graph.empty() ||
                          !o.load_graph.empty()))
  {
    throw std::invalid_argument(
        "--loops, --min-loop-separation, --keyframe-distance, --save-graph and --load-graph need --loop-closure");
  }
  if (!o.localize.empty() && o.loop_closure)
  {
    throw std::invalid_argument("--localize does not map: no --loop-closure");
  }
  if (!o.localize.empty() && o.initial_pose.empty() && !o.global)
  {
    throw std::invalid_argument("--localize needs --initial-pose or --global");
  }
  return true;
}
}  // namespace

int main(int argc, char** argv)
{
  Options opt;
  try
  {
    parse(argc, argv, opt);
  }
  catch (const std::exception& e)
  {
    std::cerr << "aloam_offline: " << e.what() << "\n\n" << kUsage;
    return 2;
  }
  const auto sensor = aloam::SensorModel::fromPreset(opt.sensor);
  if (!sensor)
  {
    std::cerr << "aloam_offline: unknown sensor " << opt.sensor << "\n\n" << kUsage;
    return 2;
  }

  aloam::PipelineConfig config = opt.kitti_dir.empty() ? aloam::PipelineConfig() : aloam::io::kittiPipelineConfig();
  config.registration.sensor = *sensor;
  config.registration.scan_period = sensor->scanPeriod();
  // The nodelets' time policy. Sweeps that come every keep_every-th period are not gaps (on a throttled
  // topic, raise the nodelets' ~max_gap_sweeps the same way).
  config.stamps.scan_period = sensor->scanPeriod();
  config.stamps.max_gap_sweeps *= static_cast<double>(opt.keep_every);
  if (opt.minimum_range)
  {
    config.registration.minimum_range = *opt.minimum_range;
  }
  config.odometry.deskew = opt.deskew;
  if (opt.odometry_min_constraint)
  {
    config.odometry.min_constraint = *opt.odometry_min_constraint;
  }
  if (opt.mapping_min_constraint)
  {
    config.mapping.min_constraint = *opt.mapping_min_constraint;
  }
  if (opt.corner_leaf)
  {
    config.mapping.corner_leaf_size = *opt.corner_leaf;
  }
  if (opt.surf_leaf)
  {
    config.mapping.surf_leaf_size = *opt.surf_leaf;
  }
  if (opt.baseline)
  {
    config.mapping.leaf_min_scale = 1.0;
    config.odometry.degeneracy_remap = false;
    config.odometry.time_scaling = false;
    config.odometry.motion_hypotheses = false;
    config.odometry.nearby_elevation_deg = 0.0;
    config.mapping.degeneracy_remap = false;
    config.mapping.hard_frame_outer_iterations = 0;
    config.mapping.deskew_first_late = false;
    config.mapping.sweep_span = false;
  }
  if (opt.sweep_span)
  {
    config.mapping.sweep_span = *opt.sweep_span;
  }
  if (opt.span_start_weight)
  {
    config.mapping.span_start_weight = *opt.span_start_weight;
  }
  if (opt.leaf_min_scale)
  {
    config.mapping.leaf_min_scale = *opt.leaf_min_scale;
  }
  if (opt.nearby_elevation_deg)
  {
    config.odometry.nearby_elevation_deg = *opt.nearby_elevation_deg;
  }
  config.odometry.motion_hypotheses = config.odometry.motion_hypotheses && opt.motion_hypotheses;
  config.odometry.soft_remap = config.odometry.soft_remap && opt.soft_remap;
  config.mapping.soft_remap = config.mapping.soft_remap && opt.soft_remap;
  if (opt.reject_occluded)
  {
    config.registration.reject_occluded = *opt.reject_occluded;
  }
  if (opt.occlusion_continuity)
  {
    config.registration.occlusion_continuity = *opt.occlusion_continuity;
  }
  if (opt.occlusion_straight)
  {
    config.registration.occlusion_straight_tolerance = *opt.occlusion_straight;
  }
  if (opt.curvature_across_ring)
  {
    config.registration.curvature_across_ring = *opt.curvature_across_ring;
  }
  config.loop_closure = opt.loop_closure;
  config.loop.matching = config.mapping;
  if (opt.min_loop_separation)
  {
    config.loop.min_loop_separation_time = config.loop.min_loop_separation_path = *opt.min_loop_separation;
  }
  if (opt.keyframe_distance)
  {
    config.loop.keyframe_distance = *opt.keyframe_distance;
  }

  std::unique_ptr<FrameSource> source;
  try
  {
    if (!opt.kitti_dir.empty())
    {
      source = std::make_unique<KittiSource>(opt.kitti_dir, opt.kitti_vertical_correction);
    }
    else
    {
      source = std::make_unique<BagSource>(opt.bag_file, opt.topic, sensor->scanPeriod(), opt.keep_every);
    }
  }
  catch (const std::exception& e)
  {
    std::cerr << "aloam_offline: " << e.what() << "\n";
    return 1;
  }

  const std::size_t end =
      opt.max_frames > 0 ? std::min(opt.start_frame + opt.max_frames, source->size()) : source->size();
  if (opt.start_frame >= end)
  {
    std::cerr << "aloam_offline: --start-frame " << opt.start_frame << " is past the last frame\n";
    return 2;
  }
  if (!opt.localize.empty())
  {
    return localize(opt, config, *source, end);
  }
  const std::size_t frames = end - opt.start_frame;
  std::cerr << "aloam_offline: " << frames << " frames, sensor " << opt.sensor
            << (opt.deskew ? ", deskew on" : ", deskew off") << (opt.baseline ? ", baseline (81f6493) handling" : "")
            << "\n";

  aloam::Pipeline pipeline(config);
  if (!opt.load_graph.empty())
  {
    try
    {
      aloam::Pose initial;
      if (!opt.initial_pose.empty())
      {
        const auto pose = aloam::poseFromXyzRpy(opt.initial_pose);
        if (!pose)
        {
          throw std::invalid_argument("--initial-pose is not \"x y z roll pitch yaw\": \"" + opt.initial_pose + "\"");
        }
        initial = *pose;
      }
      const auto start = std::chrono::steady_clock::now();
      aloam::GraphFile file = aloam::readGraphFile(opt.load_graph);
      const double read_ms = msSince(start);
      std::vector<std::string> warnings = aloam::graphSettingsWarnings(file.info, graphInfo(opt, config));
      const std::size_t keyframes = file.graph.keyframes.size(), edges = file.graph.edges.size();
      for (const std::string& w : pipeline.loadGraph(std::move(file.graph), initial))
      {
        warnings.push_back(w);
      }
      for (const std::string& w : warnings)
      {
        std::cerr << "aloam_offline: warning: " << w << "\n";
      }
      std::fprintf(stderr, "loaded graph %s: %zu keyframes, %zu edges (read in %.1f ms, loaded in %.1f ms)\n",
                   opt.load_graph.c_str(), keyframes, edges, read_ms, msSince(start) - read_ms);
    }
    catch (const std::exception& e)
    {
      std::cerr << "aloam_offline: " << e.what() << "\n";
      return 1;
    }
  }
  aloam::eval::Trajectory trajectory, odometry_trajectory;
  std::vector<double> stamps;
  std::vector<double> registration_ms, odometry_ms, mapping_ms, update_ms, pose_ms, total_ms;
  std::size_t rejected = 0, degraded_odometry = 0, degraded_mapping = 0, remapped_odometry = 0, remapped_mapping = 0,
              span_solved = 0;
  std::size_t hypotheses_tried = 0, hypotheses_kept = 0;
  std::map<double, std::size_t> leaf_scales;  // frames mapped with each leaf scale
  std::vector<double> inlier_shares, loop_ms;
  // The mapped poses, which loop closure moves after the fact (the trajectory written at the end).
  std::vector<aloam::Pose> mapped;
  Frame frame;
  const bool tty = isatty(fileno(stderr));
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = opt.start_frame; i < end; ++i)
  {
    aloam::Pose pose = mapped.empty() ? aloam::Pose() : mapped.back();
    aloam::Pose odometry_pose = odometry_trajectory.empty() ? aloam::Pose() : aloam::Pose(odometry_trajectory.back());
    if (source->read(i, frame))
    {
      const aloam::PipelineOutput out = pipeline.process(frame.cloud, frame.stamp, frame.has_ring, frame.has_time);
      registration_ms.push_back(out.timings.registration_ms);
      if (out.status == aloam::PipelineStatus::kOk)
      {
        pose = out.mapping.pose;
        odometry_pose = out.odometry.pose;
        odometry_ms.push_back(out.timings.odometry_ms);
        mapping_ms.push_back(out.timings.mapping_ms);
        update_ms.push_back(out.timings.update_ms);
        pose_ms.push_back(out.timings.latencyPathMs());
        total_ms.push_back(out.timings.totalMs());
        degraded_odometry += out.odometry.status == aloam::OdometryStatus::kDegraded;
        degraded_mapping += out.mapping.status == aloam::MappingStatus::kDegraded;
        remapped_odometry += out.odometry.status == aloam::OdometryStatus::kRemapped;
        remapped_mapping += out.mapping.status == aloam::MappingStatus::kRemapped;
        hypotheses_tried += out.odometry.hypotheses_tried;
        hypotheses_kept += out.odometry.hypothesis > 0;
        ++leaf_scales[out.mapping.leaf_scale];
        span_solved += out.mapping.span_solved ? 1 : 0;
        if (out.odometry.status != aloam::OdometryStatus::kInitialized)
        {
          inlier_shares.push_back(out.odometry.inlier_share);
        }
        const aloam::LoopClosure* loops = pipeline.loopClosure();
        if (loops && loops->keyframeAt(out.mapping.stamp) < loops->keyframes().size())
        {
          loop_ms.push_back(out.timings.loop_ms);
          if (out.loop.optimized)
          {
            // The frames so far follow their keyframes; this frame's pose is corrected already.
            loops->correctPoses(stamps, out.loop.keyframes_before, mapped);
          }
          for (const aloam::LoopRecord& r : out.loop.tried)
          {
            if (r.source == aloam::LoopSource::kSessionStart)
            {
              std::cerr << (tty ? "\n" : "") << "frame " << i << ": "
                        << (r.accepted ? "tied to the loaded graph (keyframe " + std::to_string(r.from) + ")"
                                       : "not tied to the loaded graph: " + r.reason)
                        << "\n";
            }
            else if (r.accepted)
            {
              std::cerr << (tty ? "\n" : "") << "loop closed: frame " << i << ", keyframe " << r.to << " to " << r.from
                        << " (" << r.correction_m << " m, graph " << out.loop.graph.ms << " ms)\n";
            }
          }
        }
        if (std::getenv("ALOAM_OFFLINE_VERBOSE"))
        {
          std::cerr << "frame " << i << " odometry status " << static_cast<int>(out.odometry.status) << " inliers "
                    << out.odometry.inlier_share << " hypothesis " << out.odometry.hypothesis << " mapping status "
                    << static_cast<int>(out.mapping.status) << " motion " << out.odometry.motion.t.transpose()
                    << " odometry matches " << out.odometry.corner_matches << "/" << out.odometry.plane_matches
                    << " constraint " << out.odometry.constraint << " weak " << aloam::describe(out.odometry.degenerate)
                    << "\n";
        }
      }
      else
      {
        ++rejected;
      }
    }
    else
    {
      ++rejected;
    }
    mapped.push_back(pose);  // a rejected frame repeats the last pose
    odometry_trajectory.push_back(odometry_pose.isometry());
    stamps.push_back(frame.stamp);
    showProgress(i + 1 - opt.start_frame, frames,
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), tty);
  }

  const aloam::LoopClosure* loops = pipeline.loopClosure();
  for (const aloam::Pose& pose : mapped)
  {
    trajectory.push_back(pose.isometry());
  }
  try
  {
    aloam::eval::writeKittiPoses(opt.trajectory, trajectory);
    std::cout << "trajectory: " << opt.trajectory << " (" << trajectory.size() << " poses"
              << (loops ? ", loop-corrected" : "") << ")\n";
    if (loops && !opt.loops.empty())
    {
      writeLoops(opt.loops, *loops, *source);
      std::cout << "loops: " << opt.loops << "\n";
    }
    if (!opt.odometry_trajectory.empty())
    {
      aloam::eval::writeKittiPoses(opt.odometry_trajectory, odometry_trajectory);
      std::cout << "odometry trajectory: " << opt.odometry_trajectory << "\n";
    }
    if (!opt.tum.empty())
    {
      aloam::eval::writeTumTrajectory(opt.tum, trajectory, stamps);
      std::cout << "tum trajectory: " << opt.tum << "\n";
    }
    if (!opt.map.empty())
    {
      aloam::Cloud map;
      pipeline.mapping().map().collectAll(map);
      if (map.empty() || pcl::io::savePCDFileBinary(opt.map, map) != 0)
      {
        throw std::runtime_error("cannot write map " + opt.map);
      }
      std::cout << "map: " << opt.map << " (" << map.size() << " points)\n";
    }
    if (!opt.save_graph.empty())
    {
      const auto start = std::chrono::steady_clock::now();
      const aloam::LoopGraph graph = loops->exportGraph();
      aloam::writeGraphFile(opt.save_graph, graph, graphInfo(opt, config));
      const double write_ms = msSince(start);
      std::cout << "saved graph: " << opt.save_graph << " (" << graph.keyframes.size() << " keyframes, "
                << graph.edges.size() << " edges, " << fs::file_size(opt.save_graph) << " bytes, written in "
                << std::lround(write_ms) << " ms)\n";
    }
    if (!opt.save_map.empty())
    {
      aloam::Cloud corners, surfs;
      aloam::splitMap(pipeline.mapping().map(), corners, surfs);
      aloam::MapMetadata metadata;
      metadata.sensor = opt.sensor;
      metadata.cube_size = config.mapping.cube_size;
      metadata.corner_leaf_size = config.mapping.corner_leaf_size;
      metadata.surf_leaf_size = config.mapping.surf_leaf_size;
      std::vector<Eigen::Vector3d> positions;
      for (const Eigen::Isometry3d& pose : trajectory)
      {
        positions.push_back(pose.translation());
      }
      metadata.trajectory = aloam::thinnedPositions(positions, kTrajectorySpacing);
      aloam::writeMapFile(opt.save_map, corners, surfs, metadata);
      std::cout << "saved map: " << opt.save_map << " (" << corners.size() << " edge, " << surfs.size()
                << " plane points) + " << aloam::mapSidecarPath(opt.save_map) << "\n";
    }
  }
  catch (const std::exception& e)
  {
    std::cerr << "aloam_offline: " << e.what() << "\n";
    return 1;
  }

  std::cout << "frames: " << frames << "  rejected: " << rejected << "  odometry degraded: " << degraded_odometry
            << "  mapping degraded: " << degraded_mapping << "\n";
  std::sort(inlier_shares.begin(), inlier_shares.end());
  std::cout << "odometry hypotheses: tried on " << hypotheses_tried << " frames, another start kept on "
            << hypotheses_kept << "; inlier share min " << (inlier_shares.empty() ? 0.0 : inlier_shares.front())
            << " median " << (inlier_shares.empty() ? 0.0 : inlier_shares[inlier_shares.size() / 2]) << "\n";
  std::cout << "partially degenerate (remapped): odometry " << remapped_odometry << "  mapping " << remapped_mapping
            << "\n";
  std::cout << "sweeps solved with a start and an end pose (sweep_span): " << span_solved << "\n";
  std::cout << "mapping leaf scale (frames):";
  for (const auto& [scale, count] : leaf_scales)
  {
    std::cout << " " << scale << " (" << count << ")";
  }
  std::cout << "\n";
  std::cout << "registration: " << summary(registration_ms) << "\n";
  std::cout << "odometry:     " << summary(odometry_ms) << "\n";
  std::cout << "mapping:      " << summary(mapping_ms) << "\n";
  std::cout << "to the pose:  " << summary(pose_ms) << "  (registration + odometry + mapping)\n";
  std::cout << "map update:   " << summary(update_ms) << "  (after the pose: indexing, map insertion)\n";
  std::cout << "total:        " << summary(total_ms) << "\n";
  if (loops)
  {
    const aloam::LoopClosureStats ls = loops->stats();
    if (ls.keyframes_loaded > 0)
    {
      std::cout << "loaded graph: " << ls.keyframes_loaded << " keyframes, tie of this run: " << aloam::toString(ls.tie)
                << (ls.tie_reason.empty() ? "" : " (" + ls.tie_reason + ")") << "\n";
    }
    std::cout << "loop closure: " << ls.keyframes << " keyframes (" << ls.cloud_bytes / 1024 << " KiB of clouds), "
              << ls.tried << " loops tried, " << ls.accepted << " accepted, " << ls.rejected << " rejected, "
              << ls.optimizations << " graph solves\n";
    std::cout << "loop work:    " << summary(loop_ms)
              << "  (after the pose: keyframe, verification, graph, map rebuild)\n";
  }
  return rejected == frames ? 1 : 0;
}

namespace
{
int localize(const Options& opt, const aloam::PipelineConfig& config, FrameSource& source, std::size_t end)
{
  aloam::MapData map;
  try
  {
    map = aloam::readMapFile(opt.localize);
  }
  catch (const std::exception& e)
  {
    std::cerr << "aloam_offline: " << e.what() << "\n";
    return 1;
  }
  for (const std::string& w : map.warnings)
  {
    std::cerr << "aloam_offline: warning: " << w << "\n";
  }
  aloam::LocalizerConfig lc;
  lc.mapping = config.mapping;
  lc.global_localization = opt.global;
  aloam::Localizer localizer(lc);
  localizer.loadMap(map);
  std::cerr << "aloam_offline: localizing frames " << opt.start_frame << "-" << end - 1 << " in " << opt.localize
            << " (" << map.corners.size() << " edge, " << map.surfs.size() << " plane points, "
            << localizer.globalCandidates().size() << " global candidate positions)\n";
  if (!opt.initial_pose.empty())
  {
    const auto initial = aloam::poseFromXyzRpy(opt.initial_pose);
    if (!initial)
    {
      std::cerr << "aloam_offline: --initial-pose needs six numbers \"x y z roll pitch yaw\", got \""
                << opt.initial_pose << "\"\n";
      return 2;
    }
    localizer.setInitialPose(*initial);
  }

  std::unique_ptr<std::ofstream> log;
  if (!opt.localization_log.empty())
  {
    log = std::make_unique<std::ofstream>(opt.localization_log);
    *log << "# frame stamp answered state inlier_share mean_residual matched tried fits searched candidates "
            "search_ms localize_ms x y z roll pitch yaw\n";
  }
  aloam::Pipeline pipeline(config);
  aloam::eval::Trajectory trajectory;
  std::vector<double> stamps, localize_ms;
  std::size_t answered = 0, localized = 0, lost = 0, rejected = 0;
  std::optional<std::size_t> first_localized;
  double first_search_ms = 0.0;
  Frame frame;
  aloam::Pose pose;
  const bool tty = isatty(fileno(stderr));
  const auto skip = [&]
  {
    ++rejected;
    trajectory.push_back(pose.isometry());  // the last answer stands for the frame
    stamps.push_back(frame.stamp);
  };
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = opt.start_frame; i < end; ++i)
  {
    if (!source.read(i, frame))
    {
      skip();
      continue;
    }
    const aloam::PipelineOutput out =
        pipeline.processOdometry(frame.cloud, frame.stamp, frame.has_ring, frame.has_time);
    if (out.status != aloam::PipelineStatus::kOk)
    {
      skip();
      continue;
    }
    // The pipeline applied the time policy (duplicates and late stamps dropped above, odometry reset on a
    // jump back); the localizer starts over on a jump back as in the nodelet. Odometry restarts nothing else
    // here.
    if (aloam::actionFor(out.stamp_verdict).reset)
    {
      std::cerr << "aloam_offline: frame " << i << ": time jumped back: the localizer restarts\n";
      localizer.restart(aloam::ResetReason::kJumpedBack);
    }
    const auto t0 = std::chrono::steady_clock::now();
    const aloam::LocalizationResult r = localizer.process(out.odometry);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    localize_ms.push_back(ms);
    if (r.searched && first_search_ms == 0.0)
    {
      first_search_ms = r.search_ms;
    }
    if (r.answered)
    {
      pose = r.pose;
      ++answered;
    }
    localized += r.state == aloam::LocalizationState::kLocalized;
    lost += r.state == aloam::LocalizationState::kLost;
    if (r.state == aloam::LocalizationState::kLocalized && !first_localized)
    {
      first_localized = i;
    }
    trajectory.push_back(pose.isometry());
    stamps.push_back(frame.stamp);
    if (log)
    {
      const Eigen::Matrix3d R = pose.q.toRotationMatrix();
      const Eigen::Vector3d ypr(std::atan2(R(1, 0), R(0, 0)), std::asin(std::clamp(-R(2, 0), -1.0, 1.0)),
                                std::atan2(R(2, 1), R(2, 2)));
      *log << i << " " << std::fixed << std::setprecision(6) << frame.stamp << " " << r.answered << " "
           << aloam::toString(r.state) << " " << r.fitness.inlier_share << " " << r.fitness.mean_residual << " "
           << r.fitness.matched << " " << r.fitness.tried << " " << r.fits << " " << r.searched << " " << r.candidates
           << " " << r.search_ms << " " << ms << " " << pose.t.x() << " " << pose.t.y() << " " << pose.t.z() << " "
           << ypr[2] << " " << ypr[1] << " " << ypr[0] << "\n";
    }
    if (std::getenv("ALOAM_OFFLINE_VERBOSE"))
    {
      std::cerr << "frame " << i << " " << aloam::toString(r.state) << " inliers " << r.fitness.inlier_share
                << " residual " << r.fitness.mean_residual << " mapping status " << static_cast<int>(r.mapping.status)
                << " matches " << r.mapping.corner_matches << "/" << r.mapping.plane_matches << " constraint "
                << r.mapping.constraint << " odometry " << out.odometry.pose.t.transpose() << " pose "
                << pose.t.transpose() << "\n";
    }
    showProgress(i + 1 - opt.start_frame, end - opt.start_frame,
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), tty);
  }
  try
  {
    aloam::eval::writeKittiPoses(opt.trajectory, trajectory);
    std::cout << "trajectory: " << opt.trajectory << " (" << trajectory.size() << " poses)\n";
    if (!opt.tum.empty())
    {
      aloam::eval::writeTumTrajectory(opt.tum, trajectory, stamps);
    }
    if (!opt.map_after.empty())
    {
      aloam::Cloud corners, surfs;
      aloam::splitMap(localizer.mapping().map(), corners, surfs);
      aloam::MapMetadata metadata = map.metadata;
      aloam::writeMapFile(opt.map_after, corners, surfs, metadata);
      std::cout << "map after: " << opt.map_after << "\n";
    }
  }
  catch (const std::exception& e)
  {
    std::cerr << "aloam_offline: " << e.what() << "\n";
    return 1;
  }
  if (log)
  {
    std::cout << "localization log: " << opt.localization_log << "\n";
  }
  const std::size_t frames = end - opt.start_frame;
  std::cout << "frames: " << frames << "  answered: " << answered << "  rejected: " << rejected
            << "  localized: " << localized << "  lost: " << lost
            << "  final state: " << aloam::toString(localizer.state()) << "\n";
  std::cout << "first localized frame: " << (first_localized ? std::to_string(*first_localized) : std::string("none"))
            << "  first search: " << first_search_ms << " ms\n";
  std::cout << "localization: " << summary(localize_ms) << "\n";
  return answered == 0 ? 1 : 0;
}
}  // namespace
