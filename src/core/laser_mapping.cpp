#include "aloam_nodelet/core/laser_mapping.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Eigenvalues>

#include "aloam_nodelet/core/lidar_factors.h"
#include "aloam_nodelet/core/pose_solver.h"
#include "aloam_nodelet/core/voxel_filter.h"

namespace aloam
{
namespace
{
Eigen::Vector3d vec(const Point& p)
{
  return Eigen::Vector3d(p.x, p.y, p.z);
}

// Centroid and scatter matrix of the points `index` selects.
void centroidAndScatter(const Cloud& cloud, const std::vector<int>& index, Eigen::Vector3d& centroid,
                        Eigen::Matrix3d& scatter)
{
  centroid.setZero();
  for (const int i : index)
  {
    centroid += vec(cloud.points[i]);
  }
  centroid /= static_cast<double>(index.size());
  scatter.setZero();
  for (const int i : index)
  {
    const Eigen::Vector3d d = vec(cloud.points[i]) - centroid;
    scatter += d * d.transpose();
  }
}
}  // namespace

LaserMapping::LaserMapping(LaserMappingConfig config) : config_(config), map_(config.cube_size)
{
}

void LaserMapping::setConfig(const LaserMappingConfig& config)
{
  config_ = config;
  map_.setCubeSize(config.cube_size);
}

void LaserMapping::reset()
{
  map_.clear();
  correction_ = Pose();
  evicted_total_ = 0;
}

int LaserMapping::solve(const Cloud& submap_corners, const Cloud& submap_surfs, Pose& pose, MappingResult& result)
{
  const int k_line = config_.line_neighbours;
  const int k_plane = config_.plane_neighbours;
  std::vector<int> index;
  std::vector<float> sq_dist;
  Eigen::Vector3d centroid;
  Eigen::Matrix3d scatter;

  for (int outer = 0; outer < config_.outer_iterations; ++outer)
  {
    PoseProblem problem(pose, config_.huber_delta);
    int corners = 0, planes = 0;

    for (const Point& p : corner_stack_.points)
    {
      const Point sel = transformPoint(pose, p);
      if (submap_corners.empty() || corner_tree_.nearestKSearch(sel, k_line, index, sq_dist) < k_line ||
          sq_dist.back() >= config_.line_max_sq_distance)
      {
        continue;
      }
      centroidAndScatter(submap_corners, index, centroid, scatter);
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
      // Eigenvalues ascend: a line has one dominant direction.
      if (!(eig.eigenvalues()[2] > config_.line_eigen_ratio * eig.eigenvalues()[1]))
      {
        continue;
      }
      problem.addResidual(PointToLineResidual::create(vec(p), centroid, eig.eigenvectors().col(2)));
      ++corners;
    }

    for (const Point& p : surf_stack_.points)
    {
      const Point sel = transformPoint(pose, p);
      if (submap_surfs.empty() || surf_tree_.nearestKSearch(sel, k_plane, index, sq_dist) < k_plane ||
          sq_dist.back() >= config_.plane_max_sq_distance)
      {
        continue;
      }
      centroidAndScatter(submap_surfs, index, centroid, scatter);
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
      // The neighbours must spread in two directions: points along one scan line fit every plane
      // through that line, and their "normal" may tilt freely about it.
      if (!(eig.eigenvalues()[1] > config_.plane_min_spread_ratio * eig.eigenvalues()[2]))
      {
        continue;
      }
      // The normal is the direction of least spread; PCA works for planes through the origin too.
      const Eigen::Vector3d n = eig.eigenvectors().col(0);
      const double d = -n.dot(centroid);
      bool planar = true;
      for (const int i : index)
      {
        if (std::fabs(n.dot(vec(submap_surfs.points[i])) + d) > config_.plane_max_distance)
        {
          planar = false;
          break;
        }
      }
      if (!planar)
      {
        continue;
      }
      problem.addResidual(PointToPlaneResidual::create(vec(p), n, d));
      ++planes;
    }

    result.corner_matches = corners;
    result.plane_matches = planes;
    if (corners + planes < config_.min_correspondences)
    {
      return corners + planes;
    }
    problem.solve(config_.max_iterations);
    pose = problem.pose();
    if (outer + 1 == config_.outer_iterations)
    {
      result.constraint = problem.constraintStrength(config_.constraint_lever_arm);
    }
  }
  return result.corner_matches + result.plane_matches;
}

void LaserMapping::insert(const Pose& pose)
{
  Cloud world;
  auto add = [&](const Cloud& stack, bool corners) {
    world.clear();
    world.points.reserve(stack.size());
    for (const Point& p : stack.points)
    {
      world.points.push_back(transformPoint(pose, p));
    }
    const auto touched = corners ? map_.insertCorners(world) : map_.insertSurfs(world);
    for (const CubeIndex& index : touched)
    {
      CubeMap::Cube* cube = map_.find(index);
      voxelDownsampleInPlace(corners ? cube->corners : cube->surfs,
                             corners ? config_.corner_leaf_size : config_.surf_leaf_size);
    }
  };
  add(corner_stack_, true);
  add(surf_stack_, false);
}

MappingResult LaserMapping::process(const OdometryFrame& frame)
{
  MappingResult result;
  result.stamp = frame.stamp;
  const Pose prediction = correction_ * frame.pose;
  Pose pose = prediction;

  corner_stack_.clear();
  surf_stack_.clear();
  if (frame.corners)
  {
    voxelDownsample(*frame.corners, config_.corner_leaf_size, corner_stack_);
  }
  if (frame.surfs)
  {
    voxelDownsample(*frame.surfs, config_.surf_leaf_size, surf_stack_);
  }

  auto submap_corners = std::make_shared<Cloud>();
  auto submap_surfs = std::make_shared<Cloud>();
  map_.gather(map_.indexOf(pose.t), config_.submap_half_xy, config_.submap_half_z, *submap_corners, *submap_surfs);

  if (static_cast<int>(submap_corners->size()) >= config_.min_map_corners &&
      static_cast<int>(submap_surfs->size()) >= config_.min_map_surfs)
  {
    // A kd-tree cannot index an empty cloud (possible when a minimum is configured to 0).
    if (!submap_corners->empty())
    {
      corner_tree_.setInputCloud(submap_corners);
    }
    if (!submap_surfs->empty())
    {
      surf_tree_.setInputCloud(submap_surfs);
    }
    const int matches = solve(*submap_corners, *submap_surfs, pose, result);
    const bool sane = pose.isFinite() && (pose.t - prediction.t).norm() < config_.cube_size;
    if (matches >= config_.min_correspondences && result.constraint >= config_.min_constraint && sane)
    {
      result.status = MappingStatus::kOk;
    }
    else
    {
      result.status = MappingStatus::kDegraded;
      pose = prediction;
    }
  }

  correction_ = pose * frame.pose.inverse();
  // A distorted first sweep would warp the map every later sweep registers against: the map starts
  // with the first sweep whose motion is known.
  if (!(frame.distorted && map_.cubeCount() == 0))
  {
    insert(pose);
  }
  if (config_.eviction_radius > 0.0)
  {
    result.evicted_cubes = map_.evictBeyond(pose.t, config_.eviction_radius);
    evicted_total_ += result.evicted_cubes;
  }

  result.pose = pose;
  result.correction = correction_;
  result.map_corners = map_.cornerCount();
  result.map_surfs = map_.surfCount();
  result.cubes = map_.cubeCount();
  return result;
}

}  // namespace aloam
