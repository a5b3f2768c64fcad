#include "aloam_nodelet/eval/kitti_metrics.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/SVD>

namespace aloam
{
namespace eval
{
namespace
{
constexpr double kRadToDeg = 180.0 / M_PI;

// Cumulative path length along the positions of `poses` (dist[0] = 0).
std::vector<double> pathDistances(const std::vector<Eigen::Matrix4d>& poses)
{
  std::vector<double> dist(poses.size(), 0.0);
  for (std::size_t i = 1; i < poses.size(); ++i)
  {
    const Eigen::Vector3d step = poses[i].topRightCorner<3, 1>() - poses[i - 1].topRightCorner<3, 1>();
    dist[i] = dist[i - 1] + step.norm();
  }
  return dist;
}

// Rotation angle of the 3x3 block, as in the devkit: acos(clamp((trace - 1) / 2)).
double rotationAngle(const Eigen::Matrix4d& pose)
{
  const double d = 0.5 * (pose(0, 0) + pose(1, 1) + pose(2, 2) - 1.0);
  return std::acos(std::max(-1.0, std::min(1.0, d)));
}

// Frames in a fast turn (EvalOptions::skip_turns_deg): the yaw step from the frame before exceeds the
// threshold, or did so at most `settle` frames earlier. All false when the threshold is 0.
std::vector<bool> turnFrames(const std::vector<Eigen::Matrix4d>& poses, double threshold_deg, std::size_t settle)
{
  std::vector<bool> turning(poses.size(), false);
  if (!(threshold_deg > 0.0))
  {
    return turning;
  }
  for (std::size_t i = 1; i < poses.size(); ++i)
  {
    const Eigen::Matrix4d step = poses[i - 1].inverse() * poses[i];
    if (std::fabs(std::atan2(step(1, 0), step(0, 0))) * kRadToDeg > threshold_deg)
    {
      std::fill(turning.begin() + static_cast<std::ptrdiff_t>(i),
                turning.begin() + static_cast<std::ptrdiff_t>(std::min(poses.size(), i + settle + 1)), true);
    }
  }
  return turning;
}

Eigen::Isometry3d toIsometry(const Eigen::Matrix4d& m)
{
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = m.topLeftCorner<3, 3>();
  pose.translation() = m.topRightCorner<3, 1>();
  return pose;
}

}  // namespace

EvalResult evaluate(const Trajectory& gt, const Trajectory& est, const EvalOptions& options)
{
  if (gt.size() != est.size())
  {
    throw std::invalid_argument("evaluate: ground truth has " + std::to_string(gt.size()) +
                                " poses but the estimate has " + std::to_string(est.size()));
  }
  if (gt.size() <= options.start || gt.size() - options.start < 2)
  {
    throw std::invalid_argument("evaluate: fewer than 2 frames from start frame " + std::to_string(options.start) +
                                " (trajectory has " + std::to_string(gt.size()) + ")");
  }
  if (options.step == 0)
  {
    throw std::invalid_argument("evaluate: step must be >= 1");
  }
  for (const double length : options.segment_lengths)
  {
    if (!(length > 0.0) || !std::isfinite(length))
    {
      throw std::invalid_argument("evaluate: segment lengths must be positive and finite");
    }
  }
  if (!(options.skip_turns_deg >= 0.0) || !std::isfinite(options.skip_turns_deg))
  {
    throw std::invalid_argument("evaluate: skip_turns_deg must be non-negative and finite");
  }

  const std::size_t n = gt.size() - options.start;
  std::vector<Eigen::Matrix4d> gt_m(n);
  std::vector<Eigen::Matrix4d> est_m(n);
  for (std::size_t i = 0; i < n; ++i)
  {
    gt_m[i] = gt[options.start + i].matrix();
    est_m[i] = est[options.start + i].matrix();
  }

  EvalResult result;
  result.frames = n;

  // Segment drift.
  const std::vector<double> dist = pathDistances(gt_m);
  const std::vector<bool> turning = turnFrames(gt_m, options.skip_turns_deg, options.turn_settle_frames);
  const std::size_t num_lengths = options.segment_lengths.size();
  std::vector<double> t_sums(num_lengths, 0.0);
  std::vector<double> r_sums(num_lengths, 0.0);
  std::vector<std::size_t> counts(num_lengths, 0);
  double t_total = 0.0;
  double r_total = 0.0;
  for (std::size_t first = 0; first < n; first += options.step)
  {
    const Eigen::Matrix4d gt_first_inv = gt_m[first].inverse();
    const Eigen::Matrix4d est_first_inv = est_m[first].inverse();
    for (std::size_t k = 0; k < num_lengths; ++k)
    {
      const double length = options.segment_lengths[k];
      // First frame whose distance exceeds dist[first] + length (dist is non-decreasing).
      const auto it =
          std::upper_bound(dist.begin() + static_cast<std::ptrdiff_t>(first), dist.end(), dist[first] + length);
      if (it == dist.end())
      {
        continue;
      }
      const std::size_t last = static_cast<std::size_t>(it - dist.begin());
      if (turning[first] || turning[last])
      {
        continue;
      }
      const Eigen::Matrix4d delta_gt = gt_first_inv * gt_m[last];
      const Eigen::Matrix4d delta_est = est_first_inv * est_m[last];
      const Eigen::Matrix4d error = delta_est.inverse() * delta_gt;
      const double t_err = error.topRightCorner<3, 1>().norm() / length;
      const double r_err = rotationAngle(error) / length;
      t_sums[k] += t_err;
      r_sums[k] += r_err;
      ++counts[k];
      t_total += t_err;
      r_total += r_err;
      ++result.segments;
    }
  }
  result.per_length.resize(num_lengths);
  for (std::size_t k = 0; k < num_lengths; ++k)
  {
    LengthStats& stats = result.per_length[k];
    stats.length = options.segment_lengths[k];
    stats.count = counts[k];
    if (counts[k] > 0)
    {
      stats.translation_drift_percent = 100.0 * t_sums[k] / static_cast<double>(counts[k]);
      stats.rotation_deg_per_100m = 100.0 * kRadToDeg * r_sums[k] / static_cast<double>(counts[k]);
    }
  }
  if (result.segments > 0)
  {
    const double count = static_cast<double>(result.segments);
    result.translation_drift_percent = 100.0 * t_total / count;
    result.rotation_deg_per_100m = 100.0 * kRadToDeg * r_total / count;
  }

  // Absolute trajectory error after rigid alignment of the estimated positions onto the GT.
  std::vector<Eigen::Vector3d> est_positions(n);
  std::vector<Eigen::Vector3d> gt_positions(n);
  for (std::size_t i = 0; i < n; ++i)
  {
    est_positions[i] = est_m[i].topRightCorner<3, 1>();
    gt_positions[i] = gt_m[i].topRightCorner<3, 1>();
  }
  const Eigen::Isometry3d alignment = alignRigid(est_positions, gt_positions);
  double squared_sum = 0.0;
  double max_error = 0.0;
  for (std::size_t i = 0; i < n; ++i)
  {
    const double e = (alignment * est_positions[i] - gt_positions[i]).norm();
    squared_sum += e * e;
    max_error = std::max(max_error, e);
  }
  result.ate_rmse_m = std::sqrt(squared_sum / static_cast<double>(n));
  result.ate_max_m = max_error;
  return result;
}

Trajectory cameraToLidar(const Trajectory& cam_poses, const Eigen::Isometry3d& tr)
{
  Trajectory lidar_poses;
  if (cam_poses.empty())
  {
    return lidar_poses;
  }
  lidar_poses.reserve(cam_poses.size());
  const Eigen::Matrix4d base_inv = (cam_poses.front().matrix() * tr.matrix()).inverse();
  for (const Eigen::Isometry3d& cam_pose : cam_poses)
  {
    lidar_poses.push_back(toIsometry(base_inv * cam_pose.matrix() * tr.matrix()));
  }
  return lidar_poses;
}

Eigen::Isometry3d alignRigid(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst)
{
  if (src.size() != dst.size() || src.empty())
  {
    throw std::invalid_argument("alignRigid: need two non-empty point sets of equal size");
  }
  const double count = static_cast<double>(src.size());
  Eigen::Vector3d src_mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d dst_mean = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < src.size(); ++i)
  {
    src_mean += src[i];
    dst_mean += dst[i];
  }
  src_mean /= count;
  dst_mean /= count;

  // Cross-covariance H = sum (src_i - src_mean) (dst_i - dst_mean)^T; the best rotation is V U^T.
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < src.size(); ++i)
  {
    cross += (src[i] - src_mean) * (dst[i] - dst_mean).transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cross, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d& u = svd.matrixU();
  const Eigen::Matrix3d& v = svd.matrixV();
  Eigen::Vector3d signs = Eigen::Vector3d::Ones();
  if ((v * u.transpose()).determinant() < 0.0)
  {
    signs.z() = -1.0;  // reflection fix: flip the axis of the smallest singular value
  }

  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  transform.linear() = v * signs.asDiagonal() * u.transpose();
  transform.translation() = dst_mean - transform.linear() * src_mean;
  return transform;
}

}  // namespace eval
}  // namespace aloam
