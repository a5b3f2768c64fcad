// LOAM scan registration: rings, per-point time, curvature and the four feature classes.
#pragma once

#include <cstddef>
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
  // motion (static synthetic street, edges only: +5.5 % with HDL-64; all features: +3.8 %, and -0.2 %
  // with the rejection). Grazing-beam rejection measured no effect there and is off.
  bool reject_occluded = true;           ///< no features beside a depth discontinuity on the far side
  double occlusion_gap_sq = 0.1;         ///< consecutive points this far apart (m^2) may be an occlusion
  double occlusion_max_bearing = 0.1;    ///< ... if their bearings differ by less than this (rad)
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
    std::vector<float> azimuths;  // atan2(y, x) of each point of the full cloud, without a time field
    // Per point of the full cloud (each ring touches only its own points, so threads share these).
    std::vector<float> curvature;
    std::vector<float> range;
    std::vector<std::uint8_t> picked;
    std::vector<std::int8_t> label;
  };
  /// What one thread needs and produces: its block of the input sorted into rings, then its rings' features.
  struct PartScratch
  {
    std::vector<std::vector<Point>> rings;
    std::vector<std::vector<float>> azimuths;
    bool have_start = false;  // the block's first azimuth, for the sweep's start without a time field
    double start_azimuth = 0.0;
    std::vector<int> candidates;
    Cloud less_flat_ring;
    FeatureSet features;  // sharp, less_sharp, flat, less_flat of the part's rings
    RegistrationStats stats;
  };

  ScanRegistrationConfig config_;
  std::shared_ptr<Executor> executor_;
  Scratch scratch_;
  std::vector<PartScratch> parts_;

  void bucketByRing(const Cloud& cloud, int begin, int end, bool ring_from_field, bool time_from_field,
                    PartScratch& part);
  void gatherRings(bool time_from_field, Cloud& full, std::vector<int>& ring_begin);
  void timesFromAzimuth(double start_azimuth, const std::vector<int>& ring_begin, Cloud& full);
  void extractRings(const Cloud& full, const std::vector<int>& ring_begin, int first_ring, int end_ring,
                    PartScratch& part);
  void markUnreliable(const Cloud& full, int begin, int end, RegistrationStats& stats);
  void pickSector(const Cloud& full, int begin, int end, PartScratch& part);
  void suppressNeighbours(const Cloud& full, int index, int ring_begin, int ring_end);
};

}  // namespace aloam
