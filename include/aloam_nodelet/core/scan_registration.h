// LOAM scan registration: rings, per-point time, curvature and the four feature classes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "aloam_nodelet/core/executor.h"
#include "aloam_nodelet/core/feature_set.h"
#include "aloam_nodelet/core/sensor_model.h"

namespace aloam
{
struct ScanRegistrationConfig
{
  SensorModel sensor = *SensorModel::fromPreset("VLP16");
  double scan_period = 0.1;      ///< seconds per sweep, for time from azimuth
  double minimum_range = 0.3;    ///< metres; closer returns are dropped (vehicle body)
  double maximum_range = 200.0;  ///< metres; farther returns are dropped
  bool use_ring_field = true;    ///< trust the input's ring when it has one
  bool use_time_field = true;    ///< trust the input's per-point time when it has one

  int curvature_half_window = 5;     ///< neighbours on each side in the curvature sum (LOAM: 5)
  int sectors = 6;                   ///< sectors per ring, features picked evenly from each
  double curvature_threshold = 0.1;  ///< above: edge candidate, below: plane candidate
  int max_sharp_per_sector = 2;
  int max_less_sharp_per_sector = 20;
  int max_flat_per_sector = 4;
  double suppression_gap_sq = 0.05;  ///< neighbours closer than this (m^2, consecutive) are suppressed
  double less_flat_leaf_size = 0.2;  ///< voxel leaf for the less-flat cloud of each ring (m)

  // LOAM's rejection of unreliable feature candidates. The far side of a depth discontinuity is the edge
  // of an occlusion shadow, which moves with the sensor: matched as an edge it inflates the estimated
  // motion (measured on a static synthetic street: docs/accuracy.md#measurements-behind-defaults).
  // Grazing-beam rejection measured no effect there and is off.
  bool reject_occluded = true;         ///< no features beside a depth discontinuity on the far side
  double occlusion_gap_sq = 0.1;       ///< consecutive points this far apart (m^2) may be an occlusion
  double occlusion_max_bearing = 0.1;  ///< ... if their bearings differ by less than this (rad)
  // A gap that either side's surface runs on across (a wall at a grazing angle, a concave corner) is no
  // shadow: its far side keeps its features (0 marks every gap, as LOAM does). Where the far side and the
  // near side lie on one straight line, it is a wall sampled unevenly, whose curvature is high but which
  // has no edge: it may give planes there, not edges. Measured in docs/accuracy_families.md.
  double occlusion_continuity = 0.15;     ///< ... unless one side's line passes this close (times the gap) to the other
  double occlusion_continuity_cap = 0.2;  ///< ... and at most this close (m): far gaps to another object stay shadows
  double occlusion_straight_tolerance = 0.05;  ///< ... no edges on an exempt far side this straight (m); 0: no check
  // LOAM's curvature of a return is the sum of its window's offsets from it; uneven spacing along a straight
  // stretch (a wall seen at a grazing angle) raises it without any bend. Such "edges" keep their place
  // relative to the sensor: matched against the map they pull the pose back to where the last sweep was,
  // while scan to scan they hold roll and pitch in corridors
  // (docs/accuracy_families.md#mappings-edges-need-a-bend-across-the-ring).
  bool curvature_across_ring = true;     ///< fill FeatureSet::bending: the edges whose curvature bends across
  bool reject_grazing = false;           ///< no features on surfaces nearly parallel to the beam
  double grazing_gap_ratio_sq = 0.0002;  ///< gap^2 to both neighbours above this * range^2
  int threads = 2;                       ///< threads sharing the rings of a sweep (results do not depend on it)
};

/// Turns one sweep into a FeatureSet. Holds only its configuration and reusable buffers; a sweep never
/// depends on the previous one.
class ScanRegistration
{
public:
  /// Parallel regions run on `executor` (a pipeline shares one among its stages); without one the stage
  /// makes its own, sized from the configuration's `threads`.
  explicit ScanRegistration(ScanRegistrationConfig config = {}, std::shared_ptr<Executor> executor = nullptr);

  const ScanRegistrationConfig& config() const { return config_; }
  void setConfig(const ScanRegistrationConfig& config) { config_ = config; }

  /// Extracts features from `cloud` (sensor frame, points in firing order within each ring).
  /// `has_ring` / `has_time` say whether the ring and time fields of the points are filled.
  /// Returns false (and an empty, valid `out`) when fewer points survive than one ring needs.
  bool process(const Cloud& cloud, double stamp, bool has_ring, bool has_time, FeatureSet& out);

  const std::shared_ptr<Executor>& executor() const { return executor_; }

private:
  struct Scratch
  {
    std::vector<float> azimuths;    // atan2(y, x) of each point of the full cloud, without a time field
    std::vector<double> ring_turn;  // per ring, the azimuth its points turn through in firing order
    // Per point of the full cloud (each ring touches only its own points, so threads share these).
    std::vector<float> curvature;
    std::vector<float> range;
    std::vector<std::uint8_t> picked;
    std::vector<std::int8_t> label;
  };
  /// One thread's contiguous block of the input, sorted into rings.
  struct InputBlock
  {
    std::vector<std::vector<Point>> rings;
    std::vector<std::vector<float>> azimuths;
    bool have_start = false;  // the block's first azimuth, for the sweep's start without a time field
    double start_azimuth = 0.0;
    RegistrationStats stats;
  };
  /// Consecutive rings whose features one thread extracts, and its buffers.
  struct RingGroup
  {
    Cloud less_flat_ring;
    FeatureSet features;  // sharp, less_sharp, flat, less_flat of the group's rings
    RegistrationStats stats;
  };
  /// Without a time field: the azimuth the sweep starts at and the spin's sign.
  struct SweepStart
  {
    double azimuth = 0.0;
    double direction = 1.0;
  };

  ScanRegistrationConfig config_;
  std::shared_ptr<Executor> executor_;
  Scratch scratch_;
  std::vector<InputBlock> blocks_;
  std::vector<RingGroup> groups_;

  void bucketByRing(const Cloud& cloud, int begin, int end, bool ring_from_field, bool time_from_field,
                    InputBlock& block);
  /// The blocks' rings joined into `full`, ring after ring; `ring_begin` gets each ring's start and the end.
  void gatherRings(bool time_from_field, Cloud& full, std::vector<int>& ring_begin);
  /// Ring `r` of every block copied to its place in `full` (and its azimuths, and its turn without a time field).
  void gatherRing(int r, bool time_from_field, const std::vector<int>& ring_begin, Cloud& full);
  /// The time of each point of one ring [begin, end) from its azimuth.
  void timesFromAzimuth(double start_azimuth, double direction, int begin, int end, Cloud& full);
  /// Rings [first_ring, end_ring): times (when `sweep_start` is given), curvature and features.
  void extractRings(Cloud& full, const std::vector<int>& ring_begin, int first_ring, int end_ring,
                    const SweepStart* sweep_start, RingGroup& group);
  void markUnreliable(const Cloud& full, int begin, int end, RegistrationStats& stats);
  void pickSector(const Cloud& full, int begin, int end, RingGroup& group);
  void suppressNeighbours(const Cloud& full, int index, int ring_begin, int ring_end);
};

}  // namespace aloam
