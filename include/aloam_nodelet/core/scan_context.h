// A place descriptor that does not depend on the (drifted) pose: the sweep seen from above in polar cells
// (rings of range x sectors of azimuth), each cell holding the height of its highest point, after the sweep
// is levelled by its roll and pitch (Scan Context, Kim and Kim, IROS 2018). Comparing two descriptors over
// every sector shift gives how alike the places are and the yaw between the two sweeps.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "aloam_nodelet/core/point_types.h"
#include "aloam_nodelet/core/pose.h"

namespace aloam
{
struct ScanContextConfig
{
  int rings = 20;
  int sectors = 60;
  double max_range = 60.0;  ///< m; points farther away are left out
  /// Added to a point's height above the sensor before it is stored, so that the ground (below the sensor)
  /// still counts as occupied; cells end up at max(0, z + lift).
  double lift = 2.5;
};

struct ScanContextMatch
{
  double distance = 1.0;  ///< 0: identical columns; 1: nothing alike (mean cosine distance of the columns)
  int shift = 0;          ///< sectors by which the query's columns were shifted onto the reference's
  /// Yaw of the query sweep in the reference sweep's (levelled) frame (rad).
  double yaw = 0.0;
};

class ScanContext
{
public:
  ScanContext() = default;
  /// The descriptor of sensor-frame clouds at `pose` (map <- sensor): only the pose's roll and pitch are
  /// used, to level the sweep.
  static ScanContext compute(const Cloud& corners, const Cloud& surfs, const Pose& pose,
                             const ScanContextConfig& config = {});
  /// The descriptor of these cells (rings x sectors, as cells() returns them), e.g. read back from a file.
  static ScanContext fromCells(const Eigen::MatrixXf& cells);

  bool empty() const { return cells_.size() == 0; }
  /// Mean cell value per ring: invariant to yaw, for a quick nearest-place search.
  const Eigen::VectorXf& ringKey() const { return ring_key_; }
  /// Compares this (query) with `reference` over every sector shift.
  ScanContextMatch match(const ScanContext& reference) const;
  const Eigen::MatrixXf& cells() const { return cells_; }  ///< rings x sectors

private:
  Eigen::MatrixXf cells_;
  Eigen::VectorXf ring_key_;
  Eigen::VectorXf column_norms_;
  int sectors_ = 0;
};

/// The roll and pitch of `pose` alone (yaw removed): what levels a sensor-frame point.
Eigen::Quaterniond levelling(const Pose& pose);
/// The yaw of `pose` about the vertical (rad).
double yawOf(const Pose& pose);

}  // namespace aloam
