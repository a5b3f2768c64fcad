// The pose problem both matching stages solve: a quaternion and a translation under point residuals.
#pragma once

#include <utility>
#include <vector>

#include "aloam_nodelet/core/lidar_factors.h"
#include "aloam_nodelet/core/parallel.h"
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

/// The pose problem of one correspondence search: a quaternion (Eigen's x, y, z, w order, on the
/// unit-quaternion manifold) and a translation under the robust point-to-line and point-to-plane residuals
/// of the matches found (MatchResiduals: one Ceres residual block for all of them).
class PoseProblem
{
public:
  /// `threads` share the evaluation of the residuals; the solution does not depend on it.
  PoseProblem(const Pose& initial, double huber_delta, int threads = 1);

  /// Takes every found match, lines then planes in point order; returns how many of each.
  std::pair<int, int> addMatches(const MatchSlots& slots);
  int matchCount() const { return static_cast<int>(lines_.size() + planes_.size()); }

  /// Runs at most `max_iterations` Levenberg-Marquardt iterations (none without matches).
  void solve(int max_iterations);
  Pose pose() const;

  /// How well the matches pin the pose down: the smallest eigenvalue of J^T J at the current pose (no
  /// robust loss; rotation in the manifold's tangent), with rotations expressed as the motion of a point
  /// `lever_arm` metres away (so that rotation and translation compare). The pose is then known to about
  /// (residual noise) / sqrt(value) along its weakest direction. Near 0 when some direction is
  /// unconstrained (one scan ring, a corridor, an open field); on a synthetic street about 100 for a
  /// VLP-16 sweep and 500 for an HDL-64 sweep.
  double constraintStrength(double lever_arm) const;

private:
  double q_[4];
  double t_[3];
  double huber_delta_;
  int threads_;
  std::vector<LineMatch> lines_;
  std::vector<PlaneMatch> planes_;
};

/// How the matching stages alternate correspondence search and solving.
struct MatchSolveOptions
{
  int outer_iterations = 2;  ///< searches, each followed by a solve
  int max_iterations = 4;    ///< solver iterations per solve
  int threads = 1;           ///< threads sharing the correspondence search
  int min_matches = 10;      ///< fewer matches: stop without solving
  double huber_delta = 0.1;
  double lever_arm = 10.0;  ///< for the constraint strength of the last solve
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
  return options;
}

struct MatchSolveResult
{
  int lines = 0;  ///< matches of the last search
  int planes = 0;
  double constraint = 0.0;  ///< PoseProblem::constraintStrength after the last solve (0 if none)
};

/// The loop of both matching stages: `outer_iterations` times, match every point from the current
/// `pose` (match_line(i, pose, slot) for i < line_points, match_plane likewise; independent per point,
/// so split over the threads), then solve from `pose`. `pose` ends at the last solution.
template <typename MatchLine, typename MatchPlane>
MatchSolveResult matchAndSolve(Pose& pose, std::size_t line_points, std::size_t plane_points,
                               const MatchSolveOptions& options, MatchLine&& match_line, MatchPlane&& match_plane)
{
  // Below this many points per thread, starting a thread costs more than it saves.
  constexpr int kMinPointsPerThread = 256;
  MatchSlots slots;
  slots.resize(line_points, plane_points);
  const int n_lines = static_cast<int>(line_points);
  const int n_all = n_lines + static_cast<int>(plane_points);
  MatchSolveResult result;
  for (int outer = 0; outer < options.outer_iterations; ++outer)
  {
    parallelChunks(n_all, options.threads, kMinPointsPerThread,
                   [&](int begin, int end, int)
                   {
                     for (int i = begin; i < end; ++i)
                     {
                       if (i < n_lines)
                       {
                         slots.line_found[i] = match_line(i, pose, slots.lines[i]);
                       }
                       else
                       {
                         slots.plane_found[i - n_lines] = match_plane(i - n_lines, pose, slots.planes[i - n_lines]);
                       }
                     }
                   });
    PoseProblem problem(pose, options.huber_delta, options.threads);
    const auto [lines, planes] = problem.addMatches(slots);
    result = MatchSolveResult{ lines, planes, 0.0 };
    if (lines + planes < options.min_matches)
    {
      break;
    }
    problem.solve(options.max_iterations);
    pose = problem.pose();
    if (outer + 1 == options.outer_iterations)
    {
      result.constraint = problem.constraintStrength(options.lever_arm);
    }
  }
  return result;
}

}  // namespace aloam
