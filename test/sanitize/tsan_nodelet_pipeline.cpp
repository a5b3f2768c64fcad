// The nodelet pipeline in one process, for ThreadSanitizer (test/sanitize/run_tsan_nodelet_pipeline.sh):
// a nodelet loader (the manager's own code) with the three nodelets, a played simulated drive, and, while
// it plays, dynamic_reconfigure and every service of the stages called from a thread of their own; then
// the nodelets are unloaded with sweeps still in flight. Exit 0 when poses came back for every sweep,
// every service answered and every unload returned; the sanitizer's own verdict comes on top (exit 66).
// Usage: tsan_nodelet_pipeline OUT_DIR [SWEEPS]
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <dynamic_reconfigure/Reconfigure.h>
#include <nav_msgs/Odometry.h>
#include <nodelet/loader.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_srvs/Trigger.h>

#include <aloam_nodelet/SaveGraph.h>
#include <aloam_nodelet/SaveMap.h>
#include <aloam_nodelet/SaveTrajectory.h>

#include "aloam_nodelet/ros/conversions.h"
#include "aloam_nodelet/ros/stage_messages.h"
#include "aloam_nodelet/sim/long_drive.h"

namespace
{
// Far beyond a sweep's processing time under the sanitizer (about 1 s): only a lost answer runs into it.
constexpr double kAnswerTimeout = 120.0;
constexpr double kStampOffset = 500.0;  // s added to the drive's stamps (a stamp of 0 is no time in ROS)

// The stamps seen on one topic; waits for a given stamp.
struct StampCollector
{
  std::mutex mutex;
  std::condition_variable cv;
  std::set<ros::Time> stamps;
  bool finite = true;

  void cb(const nav_msgs::Odometry::ConstPtr& msg)
  {
    std::lock_guard<std::mutex> lock(mutex);
    const auto& p = msg->pose.pose.position;
    finite = finite && std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
    stamps.insert(msg->header.stamp);
    cv.notify_all();
  }
  bool waitFor(const ros::Time& stamp)
  {
    std::unique_lock<std::mutex> lock(mutex);
    return cv.wait_for(lock, std::chrono::duration<double>(kAnswerTimeout), [&] { return stamps.count(stamp) > 0; });
  }
  std::size_t count()
  {
    std::lock_guard<std::mutex> lock(mutex);
    return stamps.size();
  }
};

// The stamps of a stage's own messages (StampedFeatureSet, StampedOdometryFrame), seen in this process.
struct StageStamps
{
  std::mutex mutex;
  std::condition_variable cv;
  std::set<ros::Time> stamps;

  template <typename M>
  void cb(const boost::shared_ptr<const M>& msg)
  {
    std::lock_guard<std::mutex> lock(mutex);
    stamps.insert(msg->header.stamp);
    cv.notify_all();
  }
  bool waitFor(const ros::Time& stamp)
  {
    std::unique_lock<std::mutex> lock(mutex);
    return cv.wait_for(lock, std::chrono::duration<double>(kAnswerTimeout), [&] { return stamps.count(stamp) > 0; });
  }
};

// Counts messages of any type (subscribed only so that the stages produce their optional outputs).
struct Counter
{
  std::atomic<int> received{ 0 };
  void cb(const sensor_msgs::PointCloud2::ConstPtr&) { ++received; }
};

// One round of calls, as a person at a console would make them during a drive: every stage
// reconfigured (a re-bucketing cube size on the mapping), the map and the trajectory saved, both resets.
struct ServiceCaller
{
  std::string out_dir;
  std::atomic<bool> stop{ false };
  std::atomic<int> calls{ 0 }, unanswered{ 0 }, failed{ 0 }, rounds{ 0 };
  std::atomic<int> maps_saved{ 0 }, trajectories_saved{ 0 }, graphs_saved{ 0 };

  void expect(bool answered, bool success, const std::string& what, const std::string& message = "")
  {
    ++calls;
    if (!answered)
    {
      ++unanswered;
      std::printf("service %s: no answer\n", what.c_str());
    }
    else if (!success)
    {
      ++failed;
      std::printf("service %s: failed: %s\n", what.c_str(), message.c_str());
    }
  }

  // The parameter list of a Reconfigure config that holds values of type T.
  static auto& parametersOf(dynamic_reconfigure::Config& c, double) { return c.doubles; }
  static auto& parametersOf(dynamic_reconfigure::Config& c, int) { return c.ints; }
  static auto& parametersOf(dynamic_reconfigure::Config& c, bool) { return c.bools; }

  template <typename T>
  void reconfigure(const std::string& node, const std::string& name, T value)
  {
    dynamic_reconfigure::Reconfigure srv;
    auto& request = parametersOf(srv.request.config, value);
    request.emplace_back();
    request.back().name = name;
    request.back().value = value;
    const bool answered = ros::service::call(node + "/set_parameters", srv);
    bool applied = false;
    for (const auto& p : parametersOf(srv.response.config, value))
    {
      applied =
          applied || (p.name == name && std::abs(static_cast<double>(p.value) - static_cast<double>(value)) < 1e-9);
    }
    expect(answered, applied, node + " set_parameters " + name);
  }

  void round(int r)
  {
    const bool odd = r % 2 == 1;
    // Loop closure on in three rounds of four: its lane work (keyframes, verification) runs beside the
    // registrations, and switching it touches the session from the reconfigure thread.
    reconfigure("/laser_mapping", "loop_closure", r % 4 != 3);
    reconfigure("/laser_mapping", "min_loop_separation", 3.0);
    reconfigure("/scan_registration", "minimum_range", odd ? 0.5 : 0.3);
    reconfigure("/laser_odometry", "max_iterations", odd ? 5 : 4);
    reconfigure("/laser_mapping", "cube_size", odd ? 40.0 : 50.0);
    reconfigure("/laser_mapping", "surf_leaf_size", odd ? 0.7 : 0.8);

    aloam_nodelet::SaveMap save_map;
    save_map.request.path = out_dir + "/map.pcd";
    const bool map_answered = ros::service::call("/laser_mapping/save_map", save_map);
    // Right after a map reset the map can be empty: an answer saying so is a correct one.
    expect(map_answered,
           save_map.response.success || save_map.response.message.find("the map is empty") != std::string::npos,
           "save_map", save_map.response.message);
    maps_saved += map_answered && save_map.response.success ? 1 : 0;

    aloam_nodelet::SaveTrajectory save_trajectory;
    save_trajectory.request.path = out_dir + "/trajectory.txt";
    save_trajectory.request.format = odd ? "tum" : "kitti";
    const bool trajectory_answered = ros::service::call("/laser_mapping/save_trajectory", save_trajectory);
    expect(trajectory_answered, save_trajectory.response.success, "save_trajectory", save_trajectory.response.message);
    trajectories_saved += trajectory_answered && save_trajectory.response.success ? 1 : 0;

    // The graph is copied under the loop closure's lock, beside its lane work. Loop closure off, or just
    // reset: an answer saying there is no graph is a correct one.
    aloam_nodelet::SaveGraph save_graph;
    save_graph.request.path = out_dir + "/site.graph";
    const bool graph_answered = ros::service::call("/laser_mapping/save_graph", save_graph);
    expect(graph_answered,
           save_graph.response.success || save_graph.response.message.find("no keyframe") != std::string::npos ||
               save_graph.response.message.find("loop_closure is off") != std::string::npos,
           "save_graph", save_graph.response.message);
    graphs_saved += graph_answered && save_graph.response.success ? 1 : 0;

    // Resets now and then only: each one restarts the map.
    if (r % 3 == 2)
    {
      // Each call before its check: the order in which function arguments are evaluated is unspecified.
      std_srvs::Trigger reset;
      const bool reset_answered = ros::service::call("/laser_mapping/reset", reset);
      expect(reset_answered, reset.response.success, "mapping reset", reset.response.message);
      std_srvs::Trigger odometry_reset;
      const bool odometry_answered = ros::service::call("/laser_odometry/reset", odometry_reset);
      expect(odometry_answered, odometry_reset.response.success, "odometry reset", odometry_reset.response.message);
    }
    ++rounds;
  }

  void run()
  {
    for (int r = 0; !stop; ++r)
    {
      round(r);
    }
  }
};

// The path of the mapped libaloam_nodelets.so (the run must test the instrumented build of it).
std::string loadedNodeletLibrary()
{
  std::ifstream maps("/proc/self/maps");
  std::string line;
  while (std::getline(maps, line))
  {
    const auto at = line.find('/');
    if (at != std::string::npos && line.find("libaloam_nodelets.so") != std::string::npos)
    {
      return line.substr(at);
    }
  }
  return "";
}

}  // namespace

int main(int argc, char** argv)
{
  ros::init(argc, argv, "tsan_nodelet_pipeline");
  if (argc < 2)
  {
    std::fprintf(stderr, "usage: tsan_nodelet_pipeline OUT_DIR [SWEEPS]\n");
    return 2;
  }
  const std::string out_dir = argv[1];
  const int sweeps = argc > 2 ? std::stoi(argv[2]) : 40;
  int failures = 0;
  const auto check = [&failures](bool ok, const std::string& what)
  {
    std::printf("%s: %s\n", ok ? "ok" : "FAILED", what.c_str());
    failures += ok ? 0 : 1;
  };

  ros::NodeHandle nh;
  ros::AsyncSpinner spinner(2);
  spinner.start();

  auto loader = std::make_unique<nodelet::Loader>(false);
  const std::vector<std::pair<std::string, std::string>> stages = {
    { "/scan_registration", "aloam_nodelet/ScanRegistration" },
    { "/laser_odometry", "aloam_nodelet/LaserOdometry" },
    { "/laser_mapping", "aloam_nodelet/LaserMapping" },
  };
  for (const auto& [name, type] : stages)
  {
    if (!loader->load(name, type, {}, {}))
    {
      check(false, "load " + name);
      return 1;
    }
  }
  std::printf("nodelet library: %s\n", loadedNodeletLibrary().c_str());

  StampCollector answers, mapped;
  StageStamps features, frames;
  Counter clouds;
  std::vector<ros::Subscriber> subs = {
    nh.subscribe("laser_features", 10, &StageStamps::cb<aloam::ros_io::StampedFeatureSet>, &features),
    nh.subscribe("laser_odom_frame", 10, &StageStamps::cb<aloam::ros_io::StampedOdometryFrame>, &frames),
    nh.subscribe("aft_mapped_to_init_high_frec", 100, &StampCollector::cb, &answers),
    nh.subscribe("aft_mapped_to_init", 100, &StampCollector::cb, &mapped),
    // The optional outputs (converted only while someone listens) run too.
    nh.subscribe("velodyne_cloud_registered", 2, &Counter::cb, &clouds),
    nh.subscribe("laser_cloud_surround", 2, &Counter::cb, &clouds),
    nh.subscribe("laser_cloud_map", 2, &Counter::cb, &clouds),
    nh.subscribe("laser_cloud_sharp", 2, &Counter::cb, &clouds),
    nh.subscribe("laser_cloud_corner_last", 2, &Counter::cb, &clouds),
  };
  ros::Publisher points_pub = nh.advertise<sensor_msgs::PointCloud2>("velodyne_points", 1);
  for (int i = 0; i < 600 && points_pub.getNumSubscribers() == 0; ++i)
  {
    ros::WallDuration(0.1).sleep();
  }
  if (points_pub.getNumSubscribers() == 0)
  {
    check(false, "scan registration subscribes to velodyne_points");
    return 1;
  }
  for (const auto& [name, type] : stages)
  {
    if (!ros::service::waitForService(name + "/set_parameters", ros::Duration(60.0)))
    {
      check(false, name + " advertises set_parameters");
      return 1;
    }
  }

  aloam::sim::LongDriveOptions drive_options;
  drive_options.column_step = 2;  // half the firings: the sanitizer slows everything about tenfold
  aloam::sim::LongDrive drive(drive_options);
  const aloam::SensorModel sensor = *aloam::SensorModel::fromPreset("VLP16");
  const auto sweepMsg = [&](int k)
  {
    auto msg = boost::make_shared<sensor_msgs::PointCloud2>();
    std_msgs::Header header;
    header.stamp = ros::Time(kStampOffset + drive.sweepStamp(k));
    header.frame_id = "velodyne";
    aloam::ros_io::toPointCloud2(drive.sweep(k, sensor), header, *msg);
    return msg;
  };

  // The played drive: each sweep waits for its full-rate and its mapped pose (so none is dropped by design
  // and the counts do not depend on the machine's speed), while the services are called all along.
  ServiceCaller caller;
  caller.out_dir = out_dir;
  std::thread service_thread(&ServiceCaller::run, &caller);
  int answered = 0, mapped_in_time = 0;
  for (int k = 0; k < sweeps; ++k)
  {
    const auto msg = sweepMsg(k);
    points_pub.publish(msg);
    answered += answers.waitFor(msg->header.stamp) ? 1 : 0;
    mapped_in_time += mapped.waitFor(msg->header.stamp) ? 1 : 0;
  }
  // At least one full round of calls overlapped the drive.
  while (caller.rounds.load() < 1)
  {
    ros::WallDuration(0.1).sleep();
  }
  caller.stop = true;
  service_thread.join();

  check(answered == sweeps,
        std::to_string(answered) + " of " + std::to_string(sweeps) + " sweeps answered at full rate");
  check(mapped_in_time == sweeps, std::to_string(mapped_in_time) + " of " + std::to_string(sweeps) + " sweeps mapped");
  check(answers.finite && mapped.finite, "every pose finite");
  check(caller.unanswered.load() == 0 && caller.failed.load() == 0,
        std::to_string(caller.calls.load()) + " service calls in " + std::to_string(caller.rounds.load()) +
            " rounds, " + std::to_string(caller.unanswered.load()) + " unanswered, " +
            std::to_string(caller.failed.load()) + " failed");
  check(caller.maps_saved.load() > 0 && caller.trajectories_saved.load() > 0,
        std::to_string(caller.maps_saved.load()) + " maps and " + std::to_string(caller.trajectories_saved.load()) +
            " trajectories saved (and " + std::to_string(caller.graphs_saved.load()) + " graphs)");
  check(clouds.received.load() > 0, std::to_string(clouds.received.load()) + " optional clouds received");

  // Unloading with sweeps in flight: a burst of sweeps, not waited for; then each stage is unloaded just as
  // a sweep reaches it (mapping first, once odometry has published the frame; odometry once registration
  // has published the features; registration right after a sweep is sent), so that its callback is likely
  // running while the unload destroys it. Waits that run out only lose that overlap, not a check.
  for (int k = sweeps; k < sweeps + 4; ++k)
  {
    points_pub.publish(sweepMsg(k));
  }
  const auto unload_start = std::chrono::steady_clock::now();
  const auto sendAndWait = [&](int k, StageStamps& upstream)
  {
    const auto msg = sweepMsg(k);
    points_pub.publish(msg);
    upstream.waitFor(msg->header.stamp);
  };
  sendAndWait(sweeps + 4, frames);
  check(loader->unload("/laser_mapping"), "unload /laser_mapping");
  sendAndWait(sweeps + 5, features);
  check(loader->unload("/laser_odometry"), "unload /laser_odometry");
  points_pub.publish(sweepMsg(sweeps + 6));
  check(loader->unload("/scan_registration"), "unload /scan_registration");
  loader.reset();
  std::printf("unloaded in %.2f s\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - unload_start).count());
  spinner.stop();
  subs.clear();
  points_pub.shutdown();

  std::printf("%s: %d checks failed\n", failures == 0 ? "PASSED" : "FAILED", failures);
  ros::shutdown();
  return failures == 0 ? 0 : 1;
}
