// A pose graph on Ceres: keyframe poses joined by relative-pose edges (odometry between consecutive
// keyframes, loops between revisits), solved for the poses that agree best with all edges. Loop edges carry
// a robust loss, so that a wrong loop that slipped through verification pulls less than the true ones.
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "aloam_nodelet/core/pose.h"

namespace aloam
{
struct PoseGraphEdge
{
  std::size_t from = 0;
  std::size_t to = 0;
  Pose measured;  ///< from <- to: the pose of `to` in the frame of `from`
  /// Square root of the measurement's information: the residual (translation x y z in m, in the frame of
  /// `from`, then the rotation vector in rad) is multiplied by it. sqrtInformation(sigmas) gives the
  /// diagonal case; a loop registered with a weak direction carries less information along it.
  Eigen::Matrix<double, 6, 6> sqrt_information = Eigen::Matrix<double, 6, 6>::Identity() * 10.0;
  bool loop = false;    ///< loop edges get the robust loss and the consistency check
  bool enabled = true;  ///< false: left out of every solve (a loop found inconsistent with the others)

  /// A finite measurement and a finite, non-zero information: what the graph (and a saved graph) accepts.
  bool isUsable() const;
};

/// The square-root information of independent errors with these standard deviations, the same along x y z:
/// translation (m) and rotation (rad).
Eigen::Matrix<double, 6, 6> sqrtInformation(double sigma_translation, double sigma_rotation);

struct PoseGraphSummary
{
  bool solved = false;  ///< the solver ran and returned a usable solution
  int iterations = 0;
  double initial_cost = 0.0;
  double final_cost = 0.0;
  double ms = 0.0;
  std::vector<std::size_t> disabled;  ///< loop edges this solve found inconsistent and left out
};

struct PoseGraphOptions
{
  int max_iterations = 50;
  /// Loop edges disagreeing with the solution by more than this whitened error (norm of the 6 residuals
  /// in sigmas) are left out and the graph solved again, the worst first, while two or more remain.
  double outlier_error = 5.0;
  /// Cauchy scale of the loop edges in the final solve (in sigmas; 0: none). The final solve starts from
  /// the consistent solution, where a true loop is already near its measurement, so the loss does not
  /// mistake a large true correction for an outlier. At the outlier bound a loop keeps half its weight.
  double loop_loss_scale = 5.0;
};

class PoseGraph
{
public:
  /// Adds a node at an initial pose; returns its index. The first node is held fixed (the map's origin).
  std::size_t addNode(const Pose& initial);
  void addEdge(const PoseGraphEdge& edge);

  /// Moves the poses to minimise the whitened residuals of the enabled edges (Levenberg-Marquardt): first
  /// with plain squares, leaving out the loops that disagree with the others (PoseGraphOptions), then with
  /// the robust loss on the loops.
  PoseGraphSummary optimize(const PoseGraphOptions& options = {});

  std::size_t size() const { return poses_.size(); }
  const Pose& pose(std::size_t i) const { return poses_[i]; }
  void setPose(std::size_t i, const Pose& pose) { poses_[i] = pose; }
  const std::vector<PoseGraphEdge>& edges() const { return edges_; }
  /// The edge's residual at the current poses, whitened by its information (norm of the 6-vector).
  double whitenedError(std::size_t edge) const;
  void clear();

private:
  /// One Levenberg-Marquardt solve of `poses` in place; false when it failed or left a pose non-finite.
  bool solve(std::vector<Pose>& poses, int max_iterations, double loop_loss_scale, PoseGraphSummary& summary) const;

  std::vector<Pose> poses_;
  std::vector<PoseGraphEdge> edges_;
};

}  // namespace aloam
