// aloam_kd_tree_bench: build and query time of KdTree on the clouds odometry and mapping index on
// KITTI, with the queries they make. Prints figures.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "aloam_nodelet/core/kd_tree.h"
#include "aloam_nodelet/core/pipeline.h"
#include "aloam_nodelet/core/voxel_filter.h"
#include "aloam_nodelet/io/kitti_dataset.h"

namespace
{
using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start)
{
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double median(std::vector<double> v)
{
  if (v.empty())
  {
    return 0.0;
  }
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// One indexed cloud and the queries a stage makes against it.
struct Workload
{
  aloam::Cloud indexed;
  aloam::Cloud queries;
};

struct Figures
{
  std::vector<double> build_ms, query_ms;
  std::size_t points = 0, queries = 0, found = 0;
};

// Builds and queries every workload `repeats` times; the query is nearest() (k = 1) or nearestK().
Figures measure(const std::vector<Workload>& workloads, int k, float max_sq, int repeats)
{
  Figures f;
  aloam::KdTree tree;
  std::vector<int> index;
  std::vector<float> sq;
  for (int r = 0; r < repeats; ++r)
  {
    double build = 0.0, query = 0.0;
    std::size_t found = 0;
    for (const Workload& w : workloads)
    {
      auto start = Clock::now();
      tree.build(w.indexed);
      build += msSince(start);
      start = Clock::now();
      for (const aloam::Point& q : w.queries.points)
      {
        found += k == 1 ? (tree.nearest(q, max_sq) >= 0 ? 1 : 0) : tree.nearestK(q, k, max_sq, index, sq);
      }
      query += msSince(start);
    }
    f.build_ms.push_back(build / double(workloads.size()));
    f.query_ms.push_back(query / double(workloads.size()));
    f.found = found;
  }
  for (const Workload& w : workloads)
  {
    f.points += w.indexed.size();
    f.queries += w.queries.size();
  }
  f.points /= workloads.size();
  f.queries /= workloads.size();
  return f;
}

void print(const char* name, const Figures& f)
{
  std::printf("%-16s %7zu pts %6zu queries  build %7.3f ms  queries %7.3f ms (%6.1f ns/query)  found %zu\n", name,
              f.points, f.queries, median(f.build_ms), median(f.query_ms),
              1e6 * median(f.query_ms) / double(std::max<std::size_t>(f.queries, 1)), f.found);
}
}  // namespace

int main(int argc, char** argv)
{
  if (argc < 2)
  {
    std::cerr << "usage: aloam_kd_tree_bench KITTI_DIR [REPEATS]\n";
    return 2;
  }
  const int repeats = argc > 2 ? std::max(1, std::stoi(argv[2])) : 5;
  // Run the pipeline once and keep the clouds it indexes: each sweep's edge / plane features (odometry
  // indexes them for the next sweep, which queries with its sharp / flat points) and the submap around
  // each mapped pose (queried with the next sweep's downsampled features placed at its mapped pose).
  const aloam::PipelineConfig config = aloam::io::kittiPipelineConfig();
  aloam::Pipeline pipeline(config);
  std::vector<Workload> odo_corner, odo_surf, map_corner, map_surf;
  std::shared_ptr<const aloam::FeatureSet> previous;
  aloam::Cloud scan;
  double update_ms = 0.0;
  int updates = 0;
  aloam::Cloud submap_corners, submap_surfs;
  bool have_submap = false;
  for (const std::string& file : aloam::io::listKittiScans(argv[1]))
  {
    aloam::io::readKittiScan(file, scan);
    const aloam::PipelineOutput out = pipeline.process(scan, 0.1 * double(updates), false, false);
    if (out.status != aloam::PipelineStatus::kOk)
    {
      continue;
    }
    if (previous)
    {
      odo_corner.push_back({ previous->less_sharp, out.features->sharp });
      odo_surf.push_back({ previous->less_flat, out.features->flat });
    }
    if (have_submap)
    {
      aloam::Cloud corners, surfs;
      aloam::voxelDownsample(out.features->bending ? *out.features->bending : out.features->less_sharp,
                             config.mapping.corner_leaf_size, corners);
      aloam::voxelDownsample(out.features->less_flat, config.mapping.surf_leaf_size, surfs);
      for (aloam::Point& p : corners.points)
      {
        p = aloam::transformPoint(out.mapping.pose, p);
      }
      for (aloam::Point& p : surfs.points)
      {
        p = aloam::transformPoint(out.mapping.pose, p);
      }
      map_corner.push_back({ submap_corners, corners });
      map_surf.push_back({ submap_surfs, surfs });
    }
    const aloam::CubeMap& map = pipeline.mapping().map();
    submap_corners.clear();
    submap_surfs.clear();
    map.gather(map.indexOf(out.mapping.pose.t), config.mapping.submap_half_xy, config.mapping.submap_half_z,
               submap_corners, submap_surfs);
    have_submap = true;
    previous = out.features;
    update_ms += out.timings.update_ms;
    ++updates;
  }
  if (map_surf.empty())
  {
    std::cerr << "aloam_kd_tree_bench: no sweeps in " << argv[1] << "\n";
    return 1;
  }
  std::printf("%zu sweeps, %d repeats, medians of the per-sweep means\n", map_surf.size(), repeats);
  const Figures oc = measure(odo_corner, 1, float(config.odometry.distance_sq_threshold), repeats);
  const Figures os = measure(odo_surf, 1, float(config.odometry.distance_sq_threshold), repeats);
  const Figures mc =
      measure(map_corner, config.mapping.line_neighbours, float(config.mapping.line_max_sq_distance), repeats);
  const Figures ms =
      measure(map_surf, config.mapping.plane_neighbours, float(config.mapping.plane_max_sq_distance), repeats);
  print("odometry edges", oc);
  print("odometry planes", os);
  print("mapping edges", mc);
  print("mapping planes", ms);
  const double submap_build = median(mc.build_ms) + median(ms.build_ms);
  std::printf("mapping submap build %.3f ms of the pipeline's mean update %.3f ms (%.0f %%)\n", submap_build,
              update_ms / updates, 100.0 * submap_build * updates / update_ms);
  return 0;
}
