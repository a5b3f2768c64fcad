// The pose problem both matching stages solve: a quaternion and a translation under point residuals.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "aloam_nodelet/core/lidar_factors.h"
#include "aloam_nodelet/core/executor.h"
#include "aloam_nodelet/core/pose.h"

namespace aloam
{
/// One slot per point, filled by independent searches (possibly on several threads), then added to a
/// problem in point order, so the problem does not depend on how the search was split.
struct MatchSlots
{
  std::vector<LineMatch> lines;
  std::vector<PlaneMatch> planes;
  std::vector<char> line_found, plane_found;

  void resize(std::size_t line_points, std::size_t plane_points);
};

/// A direction of the pose that the matches do not pin down (an eigenvector of J^T J with rotations scaled
/// by the lever arm, see PoseProblem::degeneracy), expressed in the frame of the pose's child (the sensor
/// at the sweep end). rotation and translation together form a unit 6-vector: `rotation` is the rotation
/// axis times the motion (m) it gives a point lever-arm metres away, `translation` is in metres.
struct DegenerateDirection
{
  Eigen::Vector3d rotation = Eigen::Vector3d::Zero();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  double eigenvalue = 0.0;  ///< constraint strength along this direction
  /// How weak: eigenvalue over the mean of the well-constrained directions' (over the strongest's when
  /// all six are weak); < 0: not known.
  double share = -1.0;
};

/// Readable form for diagnostics, e.g. "translation along (0.99, 0.01, 0.00) (forward-backward): 3 % of
/// the constraint of the other directions" or "rotation about (0.00, 0.00, 1.00) (yaw)": a part close to
/// a sensor axis is named (x forward, y left, z up), a direction mixing both names the smaller part too,
/// and the share is said when known.
std::string describe(const DegenerateDirection& direction);
/// All directions, "; "-separated ("none" if empty).
std::string describe(const std::vector<DegenerateDirection>& directions);

/// The eigen-decomposition of the scaled normal matrix of a PoseProblem.
struct Degeneracy
{
  Eigen::Matrix<double, 6, 1> eigenvalues = Eigen::Matrix<double, 6, 1>::Zero();       ///< ascending
  Eigen::Matrix<double, 6, 6> eigenvectors = Eigen::Matrix<double, 6, 6>::Identity();  ///< columns, scaled tangent
  double lever_arm = 10.0;
  double threshold = 0.0;  ///< eigenvalues below it are degenerate
  int degenerate = 0;      ///< eigenvalues below the threshold (the first `degenerate` columns)
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  ///< the pose's rotation it was taken at

  double smallest() const { return eigenvalues[0]; }
  /// The degenerate directions in the frame of the pose's child.
  std::vector<DegenerateDirection> directions() const;
};

/// The pose problem of one correspondence search: a quaternion (Eigen's x, y, z, w order, on the
/// unit-quaternion manifold) and a translation under the robust point-to-line and point-to-plane residuals
/// of the matches found. solve() runs Levenberg-Marquardt as Ceres does by default (see there) on the 6x6
/// normal equations, which are summed in parallel; MatchResiduals is the same problem as a Ceres cost
/// function, the reference the tests hold solve() to.
class PoseProblem
{
public:
  /// The evaluation of the residuals is split in `threads` chunks on `executor` (null: all on the calling
  /// thread); the solution depends on neither.
  PoseProblem(const Pose& initial, double huber_delta, int threads = 1, Executor* executor = nullptr);

  /// Takes every found match, lines then planes in point order; returns how many of each.
  std::pair<int, int> addMatches(const MatchSlots& slots);
  int matchCount() const { return static_cast<int>(lines_.size() + planes_.size()); }

  /// Runs at most `max_iterations` Levenberg-Marquardt iterations (none without matches): Ceres's trust
  /// region strategy with its default options (Jacobi scaling, initial radius 1e4, step quality 1e-3,
  /// function, gradient and parameter tolerances 1e-6, 1e-10, 1e-8), so it takes the steps
  /// ceres::Solve(DENSE_QR) takes on MatchResiduals, up to rounding (test_pose_solver). Each evaluation
  /// sums the 6x6 normal equations on the executor; Ceres copied, checked and factored the full Jacobian
  /// on one thread and evaluated accepted points twice: its solves took about 3 times as long, for the
  /// same trajectory (docs/performance.md#pose-solver).
  void solve(int max_iterations);
  Pose pose() const;

  /// How well the matches pin the pose down: the smallest eigenvalue of J^T J at the current pose (no
  /// robust loss; rotation in the manifold's tangent), with rotations expressed as the motion of a point
  /// `lever_arm` metres away (so that rotation and translation compare). The pose is then known to about
  /// (residual noise) / sqrt(value) along its weakest direction. Near 0 when some direction is
  /// unconstrained (one scan ring, a corridor, an open field); on a synthetic street about 100 for a
  /// VLP-16 sweep and 500 for an HDL-64 sweep.
  double constraintStrength(double lever_arm) const;

  /// The eigen-decomposition behind constraintStrength() at the current pose: tangent (rotation applied
  /// on the left, i.e. in the parent frame, times `lever_arm`; translation in m). Directions with an
  /// eigenvalue below `threshold` count as degenerate. Without matches every direction is (eigenvalues 0).
  Degeneracy degeneracy(double lever_arm, double threshold) const;

  /// Matches whose residual (distance to the line or plane, no robust loss) at the current pose is below
  /// `max_residual` (m).
  int inliers(double max_residual) const;

  /// Solution remapping (Zhang, Kaess & Singh, ICRA 2016): keeps the step from `prior` to the current pose
  /// only along the well-constrained directions of `degeneracy` and the prior along the degenerate ones.
  /// The step is taken in the scaled tangent at `prior` (rotation Log(q q_prior^-1), translation t - t_prior).
  /// `soft`: a degenerate direction keeps the share eigenvalue / threshold of its step instead of none, as a
  /// prior along it would that tops its constraint up to the threshold (weak but real constraints count).
  void remap(const Pose& prior, const Degeneracy& degeneracy, bool soft = false);

private:
  /// The terms of every match at (q, t), robustified with `huber_delta`, summed in blocks of a fixed size
  /// on the executor and then in block order (the same sums for any thread count).
  NormalTerms terms(const double* q, const double* t, double huber_delta) const;

  double q_[4];
  double t_[3];
  double huber_delta_;
  int threads_;
  Executor* executor_;
  std::vector<LineMatch> lines_;
  std::vector<PlaneMatch> planes_;
};

/// How the matching stages alternate correspondence search and solving.
struct MatchSolveOptions
{
  int outer_iterations = 2;      ///< searches, each followed by a solve
  int max_iterations = 4;        ///< solver iterations per solve
  int threads = 1;               ///< chunks of the correspondence search (and of the residuals)
  Executor* executor = nullptr;  ///< runs the chunks (null: all on the calling thread)
  int min_matches = 10;          ///< fewer matches: stop without solving
  double huber_delta = 0.1;
  double lever_arm = 10.0;  ///< for the constraint strength of the last solve
  /// Eigenvalues of the scaled normal matrix below this are degenerate directions.
  double min_constraint = 0.0;
  /// Solution remapping: after every solve, keep the pose from before the solve along degenerate
  /// directions (PoseProblem::remap). Off: the solves run unchanged and only the last is analysed.
  bool remap = false;
  /// With remapping, degenerate directions keep part of the solve's step (PoseProblem::remap, `soft`).
  bool soft_remap = false;
  /// With remapping, a solve with more degenerate directions than this keeps the prior along all six: so
  /// few constrained directions come from broken input (one point repeated, a handful of matches) more
  /// often than from geometry (a corridor leaves 1, an open floor 3).
  int max_degenerate = 3;
  /// > 0: after the last solve, count the points whose match lies within this (m) of the solved pose
  /// (MatchSolveResult::inlier_share). 0: not counted.
  double inlier_residual = 0.0;
  /// Factor on the squared correspondence search radius of the first search (the later searches use 1): a
  /// start far from the truth finds its matches farther away.
  double first_search_scale = 1.0;
};

/// The options of a stage whose configuration names them alike (LaserOdometryConfig, LaserMappingConfig).
template <typename StageConfig>
MatchSolveOptions matchSolveOptionsOf(const StageConfig& config)
{
  MatchSolveOptions options;
  options.outer_iterations = config.outer_iterations;
  options.max_iterations = config.max_iterations;
  options.threads = config.threads;
  options.min_matches = config.min_correspondences;
  options.huber_delta = config.huber_delta;
  options.lever_arm = config.constraint_lever_arm;
  options.min_constraint = config.min_constraint;
  options.remap = config.degeneracy_remap;
  options.soft_remap = config.soft_remap;
  options.max_degenerate = config.max_degenerate_directions;
  options.inlier_residual = config.inlier_residual;
  return options;
}

struct MatchSolveResult
{
  int lines = 0;  ///< matches of the last search
  int planes = 0;
  double constraint = 0.0;  ///< PoseProblem::constraintStrength after the last solve (0 if none)
  /// Degenerate directions of the last solve (before remapping it), in the frame of the pose's child.
  std::vector<DegenerateDirection> degenerate;
  bool remapped = false;  ///< the last solve was remapped (some but not all directions degenerate)
  /// Share of all points offered (line and plane points) whose last match lies within
  /// MatchSolveOptions::inlier_residual of the final pose (0 when not counted or not solved).
  double inlier_share = 0.0;
};

/// The loop of both matching stages: `outer_iterations` times, match every point from the current
/// `pose` (match_line(i, pose, scale, slot) for i < line_points, match_plane likewise, `scale` the factor
/// on the squared search radius: first_search_scale in the first search, 1 after; independent per point,
/// so split over the threads), then solve from `pose`. `pose` ends at the last solution. A slot keeps what
/// its matcher last wrote: a matcher that knows a point's match still holds at the new pose may leave the
/// slot as it is and return its previous verdict. With
/// `options.remap`, every solve is remapped onto the directions it constrains (PoseProblem::remap from the
/// pose before the solve); a solve that constrains no direction leaves the pose where it was.
template <typename MatchLine, typename MatchPlane>
MatchSolveResult matchAndSolve(Pose& pose, std::size_t line_points, std::size_t plane_points,
                               const MatchSolveOptions& options, MatchLine&& match_line, MatchPlane&& match_plane)
{
  // Below this many points a chunk costs more to hand over than it saves. Several chunks per thread, so
  // that a thread done early (edge and plane searches differ in cost, a helper may start late) takes
  // more; each point writes only its own slot, so the chunking does not change the result.
  constexpr int kMinPointsPerChunk = 256;
  MatchSlots slots;
  slots.resize(line_points, plane_points);
  const int n_lines = static_cast<int>(line_points);
  const int n_all = n_lines + static_cast<int>(plane_points);
  MatchSolveResult result;
  for (int outer = 0; outer < options.outer_iterations; ++outer)
  {
    const double scale = outer == 0 ? options.first_search_scale : 1.0;
    parallelChunks(options.executor, n_all, options.threads * kChunksPerThread, kMinPointsPerChunk,
                   [&](int begin, int end, int)
                   {
                     for (int i = begin; i < end; ++i)
                     {
                       if (i < n_lines)
                       {
                         slots.line_found[i] = match_line(i, pose, scale, slots.lines[i]);
                       }
                       else
                       {
                         slots.plane_found[i - n_lines] =
                             match_plane(i - n_lines, pose, scale, slots.planes[i - n_lines]);
                       }
                     }
                   });
    PoseProblem problem(pose, options.huber_delta, options.threads, options.executor);
    const auto [lines, planes] = problem.addMatches(slots);
    result = MatchSolveResult();
    result.lines = lines;
    result.planes = planes;
    if (lines + planes < options.min_matches)
    {
      break;
    }
    const Pose before = pose;
    problem.solve(options.max_iterations);
    if (options.remap || outer + 1 == options.outer_iterations)
    {
      const Degeneracy degeneracy = problem.degeneracy(options.lever_arm, options.min_constraint);
      result.constraint = degeneracy.smallest();
      result.degenerate = degeneracy.directions();
      if (options.remap && degeneracy.degenerate > 0)
      {
        Degeneracy weak = degeneracy;
        if (weak.degenerate > options.max_degenerate)
        {
          weak.degenerate = 6;  // too little constrained to trust: nothing of the solve is kept
        }
        problem.remap(before, weak, options.soft_remap && weak.degenerate < 6);
        result.remapped = weak.degenerate < 6;
      }
    }
    pose = problem.pose();
    if (options.inlier_residual > 0.0 && outer + 1 == options.outer_iterations && n_all > 0)
    {
      result.inlier_share = static_cast<double>(problem.inliers(options.inlier_residual)) / n_all;
    }
  }
  return result;
}

}  // namespace aloam
