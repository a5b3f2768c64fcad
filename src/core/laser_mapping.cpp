#include "aloam_nodelet/core/laser_mapping.h"

#include <algorithm>
#include <cmath>
#include <tuple>
#include <vector>

#include <Eigen/Eigenvalues>

#include "aloam_nodelet/core/parallel.h"
#include "aloam_nodelet/core/pose_solver.h"
#include "aloam_nodelet/core/voxel_filter.h"

namespace aloam
{
namespace
{
// Below this many points per thread, starting a thread costs more than it saves.
constexpr int kMinPointsPerThread = 256;

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

LaserMapping::LaserMapping(LaserMappingConfig config)
  : config_(config), map_(config.cube_size, config.corner_leaf_size, config.surf_leaf_size)
{
}

void LaserMapping::setConfig(const LaserMappingConfig& config)
{
  config_ = config;
  submap_ready_ = false;
  map_.setCubeSize(config.cube_size);
  map_.setLeafSizes(config.corner_leaf_size, config.surf_leaf_size);
}

void LaserMapping::reset()
{
  map_.clear();
  submap_ready_ = false;
  pending_insert_ = false;
  correction_ = Pose();
  evicted_total_ = 0;
}

bool LaserMapping::matchEdge(const Point& p, const Pose& pose, LineMatch& match) const
{
  thread_local std::vector<int> index;
  thread_local std::vector<float> sq_dist;
  const int k = config_.line_neighbours;
  const Point sel = transformPoint(pose, p);
  if (corner_tree_.nearestK(sel, k, static_cast<float>(config_.line_max_sq_distance), index, sq_dist) < k)
  {
    return false;
  }
  Eigen::Vector3d centroid;
  Eigen::Matrix3d scatter;
  centroidAndScatter(submap_corners_, index, centroid, scatter);
  // Closed-form 3x3 eigen-decomposition: several times faster than the iterative one, and as exact on
  // these well-scaled scatter matrices. Eigenvalues ascend: a line has one dominant direction.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(scatter);
  if (!(eig.eigenvalues()[2] > config_.line_eigen_ratio * eig.eigenvalues()[1]))
  {
    return false;
  }
  match = LineMatch{ vec(p), centroid, eig.eigenvectors().col(2) };
  return true;
}

bool LaserMapping::matchPlane(const Point& p, const Pose& pose, PlaneMatch& match) const
{
  thread_local std::vector<int> index;
  thread_local std::vector<float> sq_dist;
  const int k = config_.plane_neighbours;
  const Point sel = transformPoint(pose, p);
  if (surf_tree_.nearestK(sel, k, static_cast<float>(config_.plane_max_sq_distance), index, sq_dist) < k)
  {
    return false;
  }
  Eigen::Vector3d centroid;
  Eigen::Matrix3d scatter;
  centroidAndScatter(submap_surfs_, index, centroid, scatter);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(scatter);
  // The neighbours must spread in two directions: points along one scan line fit every plane through
  // that line, and their "normal" may tilt freely about it.
  if (!(eig.eigenvalues()[1] > config_.plane_min_spread_ratio * eig.eigenvalues()[2]))
  {
    return false;
  }
  // The normal is the direction of least spread; PCA works for planes through the origin too.
  const Eigen::Vector3d n = eig.eigenvectors().col(0);
  const double d = -n.dot(centroid);
  for (const int i : index)
  {
    if (std::fabs(n.dot(vec(submap_surfs_.points[i])) + d) > config_.plane_max_distance)
    {
      return false;
    }
  }
  match = PlaneMatch{ vec(p), n, d };
  return true;
}

int LaserMapping::solve(Pose& pose, MappingResult& result)
{
  MatchSlots slots;
  slots.resize(corner_stack_.size(), surf_stack_.size());
  const int n_corners = static_cast<int>(corner_stack_.size());
  const int n_surfs = static_cast<int>(surf_stack_.size());

  for (int outer = 0; outer < config_.outer_iterations; ++outer)
  {
    // The searches are independent per point: split them over the threads.
    parallelChunks(n_corners + n_surfs, config_.threads, kMinPointsPerThread, [&](int begin, int end, int) {
      for (int i = begin; i < end; ++i)
      {
        if (i < n_corners)
        {
          slots.line_found[i] = matchEdge(corner_stack_.points[i], pose, slots.lines[i]);
        }
        else
        {
          const int j = i - n_corners;
          slots.plane_found[j] = matchPlane(surf_stack_.points[j], pose, slots.planes[j]);
        }
      }
    });

    PoseProblem problem(pose, config_.huber_delta);
    std::tie(result.corner_matches, result.plane_matches) = problem.addMatches(slots);
    if (result.corner_matches + result.plane_matches < config_.min_correspondences)
    {
      return result.corner_matches + result.plane_matches;
    }
    problem.solve(config_.max_iterations, config_.threads);
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
  for (const bool corners : { true, false })
  {
    const Cloud& stack = corners ? corner_stack_ : surf_stack_;
    world.clear();
    world.points.reserve(stack.size());
    for (const Point& p : stack.points)
    {
      world.points.push_back(transformPoint(pose, p));
    }
    // The map merges the points into its voxels (the leaf sizes of the configuration).
    corners ? map_.insertCorners(world) : map_.insertSurfs(world);
  }
}

MappingResult LaserMapping::process(const OdometryFrame& frame)
{
  MappingResult result = registerFrame(frame);
  updateMap(result);
  return result;
}

void LaserMapping::prepareSubmap(const CubeIndex& centre)
{
  submap_corners_.clear();
  submap_surfs_.clear();
  map_.gather(centre, config_.submap_half_xy, config_.submap_half_z, submap_corners_, submap_surfs_);
  corner_tree_.build(submap_corners_);
  surf_tree_.build(submap_surfs_);
  submap_centre_ = centre;
  submap_ready_ = true;
}

MappingResult LaserMapping::registerFrame(const OdometryFrame& frame)
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

  // updateMap() prepared the submap around the previous pose; it serves unless the robot changed cube.
  const CubeIndex centre = map_.indexOf(pose.t);
  if (!submap_ready_ || centre != submap_centre_)
  {
    prepareSubmap(centre);
  }
  if (static_cast<int>(submap_corners_.size()) >= config_.min_map_corners &&
      static_cast<int>(submap_surfs_.size()) >= config_.min_map_surfs)
  {
    const int matches = solve(pose, result);
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
  result.pose = pose;
  result.correction = correction_;
  // A distorted first sweep would warp the map every later sweep registers against: the map starts
  // with the first sweep whose motion is known.
  pending_insert_ = !(frame.distorted && map_.cubeCount() == 0);
  pending_pose_ = pose;
  return result;
}

void LaserMapping::updateMap(MappingResult& result)
{
  if (pending_insert_)
  {
    insert(pending_pose_);
    pending_insert_ = false;
  }
  if (config_.eviction_radius > 0.0)
  {
    result.evicted_cubes = map_.evictBeyond(pending_pose_.t, config_.eviction_radius);
    evicted_total_ += result.evicted_cubes;
  }
  prepareSubmap(map_.indexOf(pending_pose_.t));
  result.map_corners = map_.cornerCount();
  result.map_surfs = map_.surfCount();
  result.cubes = map_.cubeCount();
}

}  // namespace aloam
