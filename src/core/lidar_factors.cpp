#include "aloam_nodelet/core/lidar_factors.h"

#include <cmath>

#include "aloam_nodelet/core/parallel.h"

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

using RowMajor34 = Eigen::Matrix<double, 3, 4, Eigen::RowMajor>;
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

Eigen::Matrix<double, 3, 4> rotationJacobian(const double* q, const Eigen::Vector3d& p)
{
  const Eigen::Vector3d v(q[0], q[1], q[2]);
  const double w = q[3];
  Eigen::Matrix<double, 3, 4> j;
  // d/dv: 2 w (v x p) -> -2 w [p]x;  2 v x (v x p) = 2 (v (v.p) - p (v.v)) -> 2 ((v.p) I + v p^T - 2 p v^T).
  j.leftCols<3>() = -2.0 * w * cross(p) +
                    2.0 * (v.dot(p) * Eigen::Matrix3d::Identity() + v * p.transpose() - 2.0 * p * v.transpose());
  j.col(3) = 2.0 * v.cross(p);
  return j;
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

void evaluateLine(const LineMatch& m, const double* q, const double* t, double* r, double* jq, double* jt)
{
  // r = (x - a) x u = -[u]x (x - a)
  const Eigen::Matrix3d minus_u_cross = -cross(m.direction);
  Eigen::Map<Eigen::Vector3d> residual(r);
  residual = minus_u_cross * (applyPose(q, t, m.point) - m.a);
  if (jq != nullptr)
  {
    Eigen::Map<RowMajor34> dq(jq);
    dq = minus_u_cross * rotationJacobian(q, m.point);
  }
  if (jt != nullptr)
  {
    Eigen::Map<RowMajor33> dt(jt);
    dt = minus_u_cross;
  }
}

void evaluatePlane(const PlaneMatch& m, const double* q, const double* t, double* r, double* jq, double* jt)
{
  r[0] = m.normal.dot(applyPose(q, t, m.point)) + m.d;
  if (jq != nullptr)
  {
    Eigen::Map<Eigen::Matrix<double, 1, 4>> dq(jq);
    dq = m.normal.transpose() * rotationJacobian(q, m.point);
  }
  if (jt != nullptr)
  {
    Eigen::Map<Eigen::Matrix<double, 1, 3>> dt(jt);
    dt = m.normal.transpose();
  }
}

MatchResiduals::MatchResiduals(const std::vector<LineMatch>& lines, const std::vector<PlaneMatch>& planes,
                               double huber_delta, int threads)
  : lines_(lines), planes_(planes), huber_delta_(huber_delta), threads_(threads)
{
  set_num_residuals(static_cast<int>(3 * lines.size() + planes.size()));
  mutable_parameter_block_sizes()->push_back(4);
  mutable_parameter_block_sizes()->push_back(3);
}

bool MatchResiduals::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const
{
  // Below this many matches per thread, handing work over costs more than it saves.
  constexpr int kMinMatchesPerThread = 512;
  const double* q = parameters[0];
  const double* t = parameters[1];
  double* jq = jacobians != nullptr ? jacobians[0] : nullptr;
  double* jt = jacobians != nullptr ? jacobians[1] : nullptr;
  const int n_lines = static_cast<int>(lines_.size());
  const int n_all = n_lines + static_cast<int>(planes_.size());
  // Rows: 3 per line match, then 1 per plane match.
  parallelChunks(n_all, threads_, kMinMatchesPerThread, [&](int begin, int end, int) {
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
        evaluateLine(lines_[i], q, t, r, row_q, row_t);
      }
      else
      {
        evaluatePlane(planes_[i - n_lines], q, t, r, row_q, row_t);
      }
      robustify(n, huber_delta_, r, row_q, row_t);
    }
  });
  return true;
}

}  // namespace aloam
