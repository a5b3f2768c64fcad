#include "aloam_nodelet/core/lidar_factors.h"

#include <cmath>

namespace aloam
{
namespace
{
Eigen::Matrix3d cross(const Eigen::Vector3d& v)
{
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

using RowMajor33 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

// Rescales the n residuals of one match so that their squared norm becomes the Huber cost
// rho(s) = 2 delta sqrt(s) - delta^2 (s = |r|^2 beyond delta^2; below, rho(s) = s and nothing changes):
// r' = g(s) r with g = sqrt(rho / s), and J' = g J + 2 g'(s) r (r^T J) for each Jacobian block given.
void robustify(int n, double delta, double* r, double* jq, double* jt)
{
  double s = 0.0;
  for (int i = 0; i < n; ++i)
  {
    s += r[i] * r[i];
  }
  if (delta <= 0.0 || s <= delta * delta)
  {
    return;
  }
  const double norm = std::sqrt(s);
  const double rho = 2.0 * delta * norm - delta * delta;
  const double g = std::sqrt(rho / s);
  const double two_dg = (delta * norm - rho) / (s * s * g);  // 2 g'(s), from rho'(s) = delta / sqrt(s)
  for (const auto& [jacobian, cols] : { std::pair<double*, int>{ jq, 4 }, std::pair<double*, int>{ jt, 3 } })
  {
    if (jacobian == nullptr)
    {
      continue;
    }
    for (int c = 0; c < cols; ++c)
    {
      double r_dot_column = 0.0;
      for (int i = 0; i < n; ++i)
      {
        r_dot_column += r[i] * jacobian[i * cols + c];
      }
      for (int i = 0; i < n; ++i)
      {
        jacobian[i * cols + c] = g * jacobian[i * cols + c] + two_dg * r[i] * r_dot_column;
      }
    }
  }
  for (int i = 0; i < n; ++i)
  {
    r[i] *= g;
  }
}
}  // namespace

PoseTerms::PoseTerms(const double* q, const double* t_data) : t(t_data[0], t_data[1], t_data[2])
{
  const Eigen::Vector3d v(q[0], q[1], q[2]);
  const double w = q[3];
  const Eigen::Matrix3d v_cross = cross(v);
  a = Eigen::Matrix3d::Identity() + 2.0 * w * v_cross + 2.0 * v_cross * v_cross;
  for (int i = 0; i < 3; ++i)
  {
    const Eigen::Matrix3d e_cross = cross(Eigen::Vector3d::Unit(i));
    d[i] = 2.0 * w * e_cross + 2.0 * (e_cross * v_cross + v_cross * e_cross);
  }
  d[3] = 2.0 * v_cross;
}

Eigen::Matrix<double, 4, 3> quaternionPlusJacobian(const double* q)
{
  const double x = q[0], y = q[1], z = q[2], w = q[3];
  Eigen::Matrix<double, 4, 3> j;
  j << w, z, -y,   //
      -z, w, x,    //
      y, -x, w,    //
      -x, -y, -z;  // d(qw)
  return j;
}

void evaluateLine(const LineMatch& m, const PoseTerms& pose, double* r, double* jq, double* jt)
{
  // r = (x - a) x u
  const Eigen::Vector3d& u = m.direction;
  const Eigen::Vector3d residual = (pose.a * m.point + pose.t - m.a).cross(u);
  r[0] = residual.x();
  r[1] = residual.y();
  r[2] = residual.z();
  if (jq != nullptr)
  {
    for (int c = 0; c < 4; ++c)
    {
      const Eigen::Vector3d column = (pose.d[c] * m.point).cross(u);
      jq[c] = column.x();
      jq[4 + c] = column.y();
      jq[8 + c] = column.z();
    }
  }
  if (jt != nullptr)
  {
    Eigen::Map<RowMajor33> dt(jt);
    dt = -cross(u);  // d((x - a) x u) / dx
  }
}

void evaluatePlane(const PlaneMatch& m, const PoseTerms& pose, double* r, double* jq, double* jt)
{
  r[0] = m.normal.dot(pose.a * m.point + pose.t) + m.d;
  if (jq != nullptr)
  {
    for (int c = 0; c < 4; ++c)
    {
      jq[c] = m.normal.dot(pose.d[c] * m.point);
    }
  }
  if (jt != nullptr)
  {
    jt[0] = m.normal.x();
    jt[1] = m.normal.y();
    jt[2] = m.normal.z();
  }
}

MatchResiduals::MatchResiduals(const std::vector<LineMatch>& lines, const std::vector<PlaneMatch>& planes,
                               double huber_delta, int threads, Executor* executor)
  : lines_(lines), planes_(planes), huber_delta_(huber_delta), threads_(threads), executor_(executor)
{
  set_num_residuals(static_cast<int>(3 * lines.size() + planes.size()));
  mutable_parameter_block_sizes()->push_back(4);
  mutable_parameter_block_sizes()->push_back(3);
}

bool MatchResiduals::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const
{
  // Below this many matches a chunk costs more to hand over than it saves; several chunks per thread
  // balance the load (rows are independent, so the chunking does not change the result).
  constexpr int kMinMatchesPerChunk = 512;
  const PoseTerms pose(parameters[0], parameters[1]);
  double* jq = jacobians != nullptr ? jacobians[0] : nullptr;
  double* jt = jacobians != nullptr ? jacobians[1] : nullptr;
  const int n_lines = static_cast<int>(lines_.size());
  const int n_all = n_lines + static_cast<int>(planes_.size());
  // Rows: 3 per line match, then 1 per plane match.
  parallelChunks(executor_, n_all, threads_ * kChunksPerThread, kMinMatchesPerChunk,
                 [&](int begin, int end, int)
                 {
                   for (int i = begin; i < end; ++i)
                   {
                     const bool line = i < n_lines;
                     const int n = line ? 3 : 1;
                     const int row = line ? 3 * i : 3 * n_lines + (i - n_lines);
                     double* r = residuals + row;
                     double* row_q = jq != nullptr ? jq + 4 * row : nullptr;
                     double* row_t = jt != nullptr ? jt + 3 * row : nullptr;
                     if (line)
                     {
                       evaluateLine(lines_[i], pose, r, row_q, row_t);
                     }
                     else
                     {
                       evaluatePlane(planes_[i - n_lines], pose, r, row_q, row_t);
                     }
                     robustify(n, huber_delta_, r, row_q, row_t);
                   }
                 });
  return true;
}

}  // namespace aloam
