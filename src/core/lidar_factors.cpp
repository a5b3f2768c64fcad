#include "aloam_nodelet/core/lidar_factors.h"

#include <cmath>
#include <initializer_list>
#include <utility>

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
// r' = g(s) r with g = sqrt(rho / s), and J' = g J + 2 g'(s) r (r^T J) for each Jacobian block given
// (row-major, n rows of the given column count; null blocks are skipped).
void robustify(int n, double delta, double* r, std::initializer_list<std::pair<double*, int>> jacobians)
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
  for (const auto& [jacobian, cols] : jacobians)
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

Eigen::Matrix3d freeAxisProjection(const LineMatch& m)
{
  // An offset d (perpendicular to u) gives r = d x u; its part along the free axis f gives (d . f) g with
  // g = f x u, and r . g = d . f. Removing r's component along g removes exactly that part.
  const Eigen::Vector3d g = m.free_axis.cross(m.direction);
  return Eigen::Matrix3d::Identity() - g * g.transpose();
}

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
  // r = P ((x - a) x u), P = I without the free axis (freeAxisProjection)
  const Eigen::Vector3d& u = m.direction;
  const Eigen::Matrix3d keep = freeAxisProjection(m);
  const Eigen::Vector3d residual = keep * (pose.a * m.point + pose.t - m.a).cross(u);
  r[0] = residual.x();
  r[1] = residual.y();
  r[2] = residual.z();
  if (jq != nullptr)
  {
    for (int c = 0; c < 4; ++c)
    {
      const Eigen::Vector3d column = keep * (pose.d[c] * m.point).cross(u);
      jq[c] = column.x();
      jq[4 + c] = column.y();
      jq[8 + c] = column.z();
    }
  }
  if (jt != nullptr)
  {
    Eigen::Map<RowMajor33> dt(jt);
    dt = -keep * cross(u);  // d((x - a) x u) / dx
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

void NormalTerms::add(const NormalTerms& other)
{
  normal += other.normal;
  gradient += other.gradient;
  cost += other.cost;
}

namespace
{
template <int Rows>
using TangentRows = Eigen::Matrix<double, Rows, 6, Eigen::RowMajor>;

// Adds one match's rows (residual r, tangent Jacobian j), robustified, to the upper triangle of `upper`,
// to `gradient` and to `cost`.
template <int Rows>
void addRows(Eigen::Matrix<double, Rows, 1> r, TangentRows<Rows> j, double delta, double* upper, double* gradient,
             double& cost)
{
  robustify(Rows, delta, r.data(), { { j.data(), 6 } });
  int k = 0;
  for (int a = 0; a < 6; ++a)
  {
    for (int b = a; b < 6; ++b, ++k)
    {
      double sum = 0.0;
      for (int i = 0; i < Rows; ++i)
      {
        sum += j(i, a) * j(i, b);
      }
      upper[k] += sum;
    }
    double sum = 0.0;
    for (int i = 0; i < Rows; ++i)
    {
      sum += j(i, a) * r[i];
    }
    gradient[a] += sum;
  }
  cost += 0.5 * r.squaredNorm();
}
}  // namespace

void accumulateMatches(const std::vector<LineMatch>& lines, const std::vector<PlaneMatch>& planes, int begin, int end,
                       const PoseTerms& pose, double huber_delta, NormalTerms& terms)
{
  // In the tangent, rotating by delta turns the rotated point y = a p by 2 delta x y: d y / d delta =
  // -2 [y]x. For a line, r = (x - a) x u, so d r / d x = -[u]x and d r / d delta = 2 [u]x [y]x =
  // 2 (y u^T - (u . y) I); for a plane, r = n . x + d, so d r / d delta = 2 (y x n)^T.
  const int n_lines = static_cast<int>(lines.size());
  double upper[21] = {};
  double gradient[6] = {};
  double cost = 0.0;
  for (int i = begin; i < end; ++i)
  {
    if (i < n_lines)
    {
      const LineMatch& m = lines[i];
      const Eigen::Vector3d y = pose.a * m.point;
      const Eigen::Vector3d& u = m.direction;
      TangentRows<3> j;
      j.leftCols<3>() = 2.0 * (y * u.transpose() - u.dot(y) * Eigen::Matrix3d::Identity());
      j.rightCols<3>() = -cross(u);
      Eigen::Vector3d r = (y + pose.t - m.a).cross(u);
      if (!m.free_axis.isZero(0.0))
      {
        const Eigen::Matrix3d keep = freeAxisProjection(m);
        r = keep * r;
        j = keep * j;
      }
      addRows<3>(r, j, huber_delta, upper, gradient, cost);
    }
    else
    {
      const PlaneMatch& m = planes[i - n_lines];
      const Eigen::Vector3d y = pose.a * m.point;
      TangentRows<1> j;
      j.leftCols<3>() = 2.0 * y.cross(m.normal).transpose();
      j.rightCols<3>() = m.normal.transpose();
      addRows<1>(Eigen::Matrix<double, 1, 1>(m.normal.dot(y + pose.t) + m.d), j, huber_delta, upper, gradient, cost);
    }
  }
  int k = 0;
  for (int a = 0; a < 6; ++a)
  {
    for (int b = a; b < 6; ++b, ++k)
    {
      terms.normal(a, b) += upper[k];
      if (b != a)
      {
        terms.normal(b, a) += upper[k];
      }
    }
    terms.gradient[a] += gradient[a];
  }
  terms.cost += cost;
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
                     robustify(n, huber_delta_, r, { { row_q, 4 }, { row_t, 3 } });
                   }
                 });
  return true;
}

}  // namespace aloam
