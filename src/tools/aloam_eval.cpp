// aloam_eval: KITTI-style evaluation of an estimated lidar trajectory against ground truth.
// Exit codes: 0 success, 1 I/O or evaluation error, 2 usage error.

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include "aloam_nodelet/eval/kitti_metrics.h"
#include "aloam_nodelet/eval/trajectory_io.h"

namespace
{
constexpr int kExitOk = 0;
constexpr int kExitError = 1;
constexpr int kExitUsage = 2;

// Parsed command line.
struct Arguments
{
  std::string gt_path;
  std::string trajectory_path;
  std::string calib_path;
  aloam::eval::EvalOptions options;
  bool help = false;
};

void printUsage(std::ostream& out)
{
  out << "Usage: aloam_eval --gt GT.txt --trajectory EST.txt [--calib calib.txt] [--start N]\n"
         "                  [--segments L1,L2,...] [--step K] [--skip-turns DEG]\n"
         "\n"
         "Evaluates an estimated lidar trajectory (KITTI pose file, poses relative to the first frame)\n"
         "against ground truth: KITTI segment drift (devkit definition) and ATE after rigid alignment.\n"
         "\n"
         "  --gt FILE          ground-truth KITTI pose file. With --calib it holds KITTI camera-0 poses\n"
         "                     and is converted to lidar poses; otherwise it is taken as lidar poses and\n"
         "                     re-based to its first frame.\n"
         "  --trajectory FILE  estimated lidar poses (KITTI format), used as given.\n"
         "  --calib FILE       KITTI calib.txt; its 'Tr:' line (velodyne -> camera 0) is used.\n"
         "  --start N          first frame to evaluate (default 0).\n"
         "  --segments LIST    comma-separated segment lengths in metres (default 100,...,800).\n"
         "  --step K           stride between segment start frames (default 1).\n"
         "  --skip-turns DEG   leave out segments that start or end in a fast turn: a frame whose true yaw\n"
         "                     changed by more than DEG degrees since the frame before, and the 3 after it.\n"
         "  --help             print this message.\n"
         "\n"
         "If the files differ in length, their common prefix is evaluated (with a warning).\n";
}

bool parseSize(const std::string& text, std::size_t& value)
{
  if (text.empty() || text.find_first_not_of("0123456789") != std::string::npos)
  {
    return false;
  }
  const char* end = text.data() + text.size();
  const std::from_chars_result res = std::from_chars(text.data(), end, value);
  return res.ec == std::errc() && res.ptr == end;
}

bool parseLengths(const std::string& text, std::vector<double>& lengths)
{
  lengths.clear();
  std::istringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ','))
  {
    char* end = nullptr;
    const double value = std::strtod(item.c_str(), &end);
    if (item.empty() || end != item.c_str() + item.size() || !std::isfinite(value) || !(value > 0.0))
    {
      return false;
    }
    lengths.push_back(value);
  }
  return !lengths.empty() && text.back() != ',';
}

// Fills `args`; on failure returns false and sets `error`.
bool parseArguments(int argc, char** argv, Arguments& args, std::string& error)
{
  for (int i = 1; i < argc; ++i)
  {
    const std::string flag = argv[i];
    if (flag == "--help" || flag == "-h")
    {
      args.help = true;
      return true;
    }
    if (i + 1 >= argc)
    {
      error = flag.rfind("--", 0) == 0 ? "missing value for " + flag : "unexpected argument '" + flag + "'";
      return false;
    }
    const std::string value = argv[++i];
    if (flag == "--gt")
    {
      args.gt_path = value;
    }
    else if (flag == "--trajectory")
    {
      args.trajectory_path = value;
    }
    else if (flag == "--calib")
    {
      args.calib_path = value;
    }
    else if (flag == "--start")
    {
      if (!parseSize(value, args.options.start))
      {
        error = "invalid --start '" + value + "' (expected a non-negative integer)";
        return false;
      }
    }
    else if (flag == "--step")
    {
      if (!parseSize(value, args.options.step) || args.options.step == 0)
      {
        error = "invalid --step '" + value + "' (expected a positive integer)";
        return false;
      }
    }
    else if (flag == "--skip-turns")
    {
      char* end = nullptr;
      const double degrees = std::strtod(value.c_str(), &end);
      if (value.empty() || *end != '\0' || !(degrees >= 0.0) || !std::isfinite(degrees))
      {
        error = "invalid --skip-turns '" + value + "' (expected a non-negative number of degrees)";
        return false;
      }
      args.options.skip_turns_deg = degrees;
    }
    else if (flag == "--segments")
    {
      if (!parseLengths(value, args.options.segment_lengths))
      {
        error = "invalid --segments '" + value + "' (expected positive numbers separated by commas)";
        return false;
      }
    }
    else
    {
      error = "unknown option '" + flag + "'";
      return false;
    }
  }
  if (args.gt_path.empty() || args.trajectory_path.empty())
  {
    error = "--gt and --trajectory are required";
    return false;
  }
  return true;
}

void printReport(const Arguments& args, const aloam::eval::EvalResult& result, std::size_t total_frames)
{
  std::printf("ground truth : %s%s\n", args.gt_path.c_str(),
              args.calib_path.empty() ? " (lidar poses)" : " (camera poses, converted with calib Tr)");
  std::printf("trajectory   : %s\n", args.trajectory_path.c_str());
  std::printf("frames evaluated: %zu (frames %zu..%zu of %zu)\n", result.frames, args.options.start, total_frames - 1,
              total_frames);
  std::printf("segments: %zu (step %zu)%s\n", result.segments, args.options.step,
              args.options.skip_turns_deg > 0.0 ? ", segments ending in fast turns left out" : "");
  std::printf("%10s %8s %12s %16s\n", "length_m", "count", "t_err_%", "r_err_deg/100m");
  for (const aloam::eval::LengthStats& stats : result.per_length)
  {
    std::printf("%10.1f %8zu %12.3f %16.3f\n", stats.length, stats.count, stats.translation_drift_percent,
                stats.rotation_deg_per_100m);
  }
  std::printf("ate_max_m: %.3f\n", result.ate_max_m);
  std::printf("translation_drift_percent: %.3f\n", result.translation_drift_percent);
  std::printf("rotation_deg_per_100m: %.3f\n", result.rotation_deg_per_100m);
  std::printf("ate_rmse_m: %.3f\n", result.ate_rmse_m);
}

int run(const Arguments& args)
{
  aloam::eval::Trajectory gt;
  aloam::eval::Trajectory est;
  try
  {
    gt = aloam::eval::readKittiPoses(args.gt_path);
    est = aloam::eval::readKittiPoses(args.trajectory_path);
    const Eigen::Isometry3d tr =
        args.calib_path.empty() ? Eigen::Isometry3d::Identity() : aloam::eval::readKittiCalibTr(args.calib_path);
    // With tr = identity this only re-bases the GT to its first frame.
    gt = aloam::eval::cameraToLidar(gt, tr);
  }
  catch (const std::exception& e)
  {
    std::cerr << "aloam_eval: error: " << e.what() << "\n";
    return kExitError;
  }

  if (gt.size() != est.size())
  {
    const std::size_t common = std::min(gt.size(), est.size());
    std::cerr << "aloam_eval: warning: ground truth has " << gt.size() << " poses, trajectory has " << est.size()
              << "; evaluating the first " << common << "\n";
    gt.resize(common);
    est.resize(common);
  }

  aloam::eval::EvalResult result;
  try
  {
    result = aloam::eval::evaluate(gt, est, args.options);
  }
  catch (const std::exception& e)
  {
    std::cerr << "aloam_eval: error: " << e.what() << "\n";
    return kExitError;
  }
  if (result.segments == 0)
  {
    std::cerr << "aloam_eval: warning: no segment fits in the trajectory; drift is NaN (try shorter --segments)\n";
  }
  printReport(args, result, gt.size());
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv)
{
  Arguments args;
  std::string error;
  if (!parseArguments(argc, argv, args, error))
  {
    std::cerr << "aloam_eval: " << error << "\n\n";
    printUsage(std::cerr);
    return kExitUsage;
  }
  if (args.help)
  {
    printUsage(std::cout);
    return kExitOk;
  }
  return run(args);
}
