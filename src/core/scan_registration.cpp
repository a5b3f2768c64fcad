#include "aloam_nodelet/core/scan_registration.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <numeric>
#include <Eigen/Core>

#include "aloam_nodelet/core/fast_atan2.h"
#include "aloam_nodelet/core/voxel_filter.h"

namespace aloam
{
namespace
{
constexpr double kTwoPi = 2.0 * M_PI;
// Rings above this count are treated as corrupt ring fields rather than real beams.
constexpr int kMaxRings = 256;
// The first return of a ring may lead the sweep start by up to a quarter turn (beam azimuth offsets)
// or lag it by up to three quarters (a beam that saw only sky at first).
constexpr double kRingStartLead = 0.5 * M_PI;
// Smaller sweeps are not worth a second thread; more than this many threads is not worth it either.
constexpr int kMinPointsForThreads = 4096;
constexpr int kMaxThreads = 8;
// Azimuth overlap tolerated past the end of a sweep before a ring is taken to start over.
constexpr double kFullTurnMargin = 5.0 * M_PI / 180.0;

enum Pick : std::uint8_t
{
  kFree = 0,
  kTaken = 1,       // chosen as a feature or suppressed next to one
  kUnreliable = 2,  // occluded or grazing: never a sharp or flat feature (still less flat, as in LOAM)
  kNoEdge = 3       // beside a gap a surface runs on across: may be flat, never sharp
};

enum Label : std::int8_t
{
  kFlat = -1,
  kPlain = 0,
  kLessSharp = 1,
  kSharp = 2
};

// Wraps an angle into [lo, lo + 2 pi).
double wrapFrom(double angle, double lo)
{
  double a = std::fmod(angle - lo, kTwoPi);
  if (a < 0.0)
  {
    a += kTwoPi;
  }
  return a + lo;
}

// A sort key: the bits of a curvature (>= 0) above a 32-bit tie breaker.
std::uint64_t sortKey(float curvature, std::uint32_t tie)
{
  std::uint32_t bits;
  std::memcpy(&bits, &curvature, sizeof bits);
  return (static_cast<std::uint64_t>(bits) << 32) | tie;
}

// Offers the eligible indices of [begin, end) to `take` in descending order of key(i) until `takes` of
// them were taken (take returns whether it took one). Taking never makes an index eligible again, so
// the indices can be found a batch at a time: the kBatch largest keys below the last batch's smallest,
// one pass each without sorting the range. A sector takes a few points from hundreds: one or two passes.
template <typename Eligible, typename Key, typename Take>
void takeBestFirst(int begin, int end, int takes, Eligible eligible, Key key, Take take)
{
  constexpr int kBatch = 16;
  std::array<std::uint64_t, kBatch> keys;
  std::array<int, kBatch> index;
  bool bounded = false;
  std::uint64_t below = 0;  // with `bounded`: only keys below this one are left
  while (takes > 0)
  {
    int n = 0;
    for (int i = begin; i < end; ++i)
    {
      if (!eligible(i))
      {
        continue;
      }
      const std::uint64_t k = key(i);
      if ((bounded && k >= below) || (n == kBatch && k <= keys[n - 1]))
      {
        continue;
      }
      // Insert in descending order (the last one drops out of a full batch).
      int at = n < kBatch ? n++ : kBatch - 1;
      for (; at > 0 && keys[at - 1] < k; --at)
      {
        keys[at] = keys[at - 1];
        index[at] = index[at - 1];
      }
      keys[at] = k;
      index[at] = i;
    }
    for (int b = 0; b < n && takes > 0; ++b)
    {
      takes -= take(index[b]) ? 1 : 0;
    }
    if (n < kBatch)
    {
      return;  // no eligible index left
    }
    bounded = true;
    below = keys[n - 1];
  }
}

float squaredGap(const Point& a, const Point& b)
{
  const float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return dx * dx + dy * dy + dz * dz;
}

// True when `to` lies on the line that `beyond` -> `from` continues across the gap, within `tolerance`
// times the gap and at most `cap` metres. `beyond` is the return two steps away from the gap on `from`'s side.
bool continuesLine(const Point& to, const Point& from, const Point& beyond, float tolerance, float cap)
{
  const Eigen::Vector3f axis(from.x - beyond.x, from.y - beyond.y, from.z - beyond.z);
  const float length = axis.norm();
  if (length < 1e-3f)
  {
    return false;
  }
  const Eigen::Vector3f step(to.x - from.x, to.y - from.y, to.z - from.z);
  const float along = step.dot(axis) / length;
  const float across = (step - along * axis / length).norm();
  return along > 0.0f && across <= std::min(tolerance * step.norm(), cap);
}

// A gap between neighbours a (index i) and b (i + 1) of one ring is no occlusion when either side's
// surface runs on across it: one surface seen at a grazing angle (a corridor wall ahead), or two that meet
// in a concave corner (wall and floor). Only a gap that neither side explains hides a surface behind an edge.
bool gapIsContinuous(const Cloud& full, int i, int begin, int end, float tolerance, float cap)
{
  const Point& a = full.points[i];
  const Point& b = full.points[i + 1];
  return continuesLine(b, a, full.points[std::max(i - 2, begin)], tolerance, cap) ||
         continuesLine(a, b, full.points[std::min(i + 3, end - 1)], tolerance, cap);
}

// Empties `f.bending`, or unsets it when the edges are not told apart (mapping then takes less_sharp).
void resetBending(FeatureSet& f, bool wanted)
{
  if (!wanted)
  {
    f.bending.reset();
    return;
  }
  if (!f.bending)
  {
    f.bending.emplace();
  }
  f.bending->clear();
}

// LOAM's curvature vector of return i: the sum of its 2w ring neighbours minus 2w times the return (its
// squared norm is the curvature). The caller keeps [i - w, i + w] within the ring.
Eigen::Vector3f curvatureVector(const Cloud& full, int i, int w)
{
  Eigen::Vector3f d = -2.0f * static_cast<float>(w) * full.points[i].getVector3fMap();
  for (int k = i - w; k <= i + w; ++k)
  {
    if (k != i)
    {
      d += full.points[k].getVector3fMap();
    }
  }
  return d;
}

// True when the returns k-w .. k+w all lie within `tolerance` (m) of the line through the two ends: a
// surface sampled unevenly (a wall at a grazing angle), whose LOAM curvature is high but which has no edge.
bool windowIsStraight(const Cloud& full, int k, int w, int begin, int end, double tolerance)
{
  const int lo = std::max(k - w, begin), hi = std::min(k + w, end - 1);
  const Eigen::Vector3f first = full.points[lo].getVector3fMap();
  const Eigen::Vector3f axis = full.points[hi].getVector3fMap() - first;
  const float length = axis.norm();
  if (length < 1e-3f)
  {
    return false;
  }
  for (int j = lo + 1; j < hi; ++j)
  {
    if ((full.points[j].getVector3fMap() - first).cross(axis).norm() > tolerance * length)
    {
      return false;
    }
  }
  return true;
}
}  // namespace

ScanRegistration::ScanRegistration(ScanRegistrationConfig config, std::shared_ptr<Executor> executor)
  : config_(std::move(config))
  , executor_(executor ? std::move(executor) : std::make_shared<Executor>(std::clamp(config_.threads, 1, kMaxThreads)))
{
}

void ScanRegistration::bucketByRing(const Cloud& cloud, int begin, int end, bool ring_from_field, bool time_from_field,
                                    InputBlock& block)
{
  auto& rings = block.rings;
  auto& azimuths = block.azimuths;
  for (auto& r : rings)
  {
    r.clear();
  }
  for (auto& a : azimuths)
  {
    a.clear();
  }
  const int model_rings = config_.sensor.numRings();
  if (!ring_from_field && static_cast<int>(rings.size()) < model_rings)
  {
    rings.resize(static_cast<std::size_t>(model_rings));
  }
  RegistrationStats& stats = block.stats;
  block.have_start = false;
  const double min_sq = config_.minimum_range * config_.minimum_range;
  const double max_sq = config_.maximum_range * config_.maximum_range;

  for (int index = begin; index < end; ++index)
  {
    const Point& in = cloud.points[index];
    if (!isFinite(in))
    {
      ++stats.invalid;
      continue;
    }
    const double range_sq = double(in.x) * in.x + double(in.y) * in.y + double(in.z) * in.z;
    if (range_sq < min_sq || range_sq > max_sq)
    {
      ++stats.out_of_range;
      continue;
    }

    int ring = -1;
    if (ring_from_field)
    {
      // Ouster drivers count rings from the top beam; the model turns them bottom-up.
      ring = in.ring < kMaxRings ? config_.sensor.ringFromField(in.ring) : -1;
    }
    else
    {
      ring = config_.sensor.ringForPoint(in.x, in.y, in.z);
    }
    if (ring < 0)
    {
      ++stats.unassigned_ring;
      continue;
    }
    if (ring >= static_cast<int>(rings.size()))
    {
      rings.resize(static_cast<std::size_t>(ring) + 1);
    }
    Point p = in;
    p.ring = static_cast<std::uint16_t>(ring);
    if (time_from_field)
    {
      p.time = std::isfinite(in.time) && in.time > 0.0f ? in.time : 0.0f;
    }
    else
    {
      const double azimuth = fastAtan2(double(in.y), double(in.x));
      if (!block.have_start)
      {
        block.have_start = true;
        block.start_azimuth = azimuth;
      }
      if (azimuths.size() < rings.size())
      {
        azimuths.resize(rings.size());
      }
      azimuths[static_cast<std::size_t>(ring)].push_back(static_cast<float>(azimuth));
    }
    rings[static_cast<std::size_t>(ring)].push_back(p);
  }
}

void ScanRegistration::gatherRing(int r, bool time_from_field, const std::vector<int>& ring_begin, Cloud& full)
{
  std::size_t at = static_cast<std::size_t>(ring_begin[r]);
  for (const InputBlock& block : blocks_)
  {
    if (r >= static_cast<int>(block.rings.size()))
    {
      continue;
    }
    std::copy(block.rings[r].begin(), block.rings[r].end(), full.points.begin() + at);
    if (!time_from_field && r < static_cast<int>(block.azimuths.size()))
    {
      std::copy(block.azimuths[r].begin(), block.azimuths[r].end(), scratch_.azimuths.begin() + at);
    }
    at += block.rings[r].size();
  }
  if (!time_from_field)
  {
    // The azimuth the ring turns through in firing order: its sign over the sweep is the spin direction.
    const auto& azimuth = scratch_.azimuths;
    double turn = 0.0;
    for (int k = ring_begin[r] + 1; k < ring_begin[r + 1]; ++k)
    {
      turn += wrapFrom(double(azimuth[k]) - azimuth[k - 1], -M_PI);
    }
    scratch_.ring_turn[r] = turn;
  }
}

void ScanRegistration::gatherRings(bool time_from_field, Cloud& full, std::vector<int>& ring_begin)
{
  std::size_t rings = 0;
  for (const InputBlock& block : blocks_)
  {
    rings = std::max(rings, block.rings.size());
  }
  // Where each ring starts in the full cloud: ring by ring, each block's share in input order, so the
  // firing order within every ring is kept.
  ring_begin.assign(rings + 1, 0);
  for (std::size_t r = 0; r < rings; ++r)
  {
    std::size_t size = 0;
    for (const InputBlock& block : blocks_)
    {
      size += r < block.rings.size() ? block.rings[r].size() : 0;
    }
    ring_begin[r + 1] = ring_begin[r] + static_cast<int>(size);
  }
  full.points.resize(static_cast<std::size_t>(ring_begin.back()));
  if (!time_from_field)
  {
    scratch_.azimuths.resize(full.size());
  }
  scratch_.ring_turn.assign(rings, 0.0);
  // The rings copy in parallel; the sweep sums their turns in ring order, whatever the chunks.
  executor_->parallelChunks(static_cast<int>(rings), config_.threads * kChunksPerThread, 1,
                            [&](int first, int last, int)
                            {
                              for (int r = first; r < last; ++r)
                              {
                                gatherRing(r, time_from_field, ring_begin, full);
                              }
                            });
  setUnorganized(full);
}

void ScanRegistration::timesFromAzimuth(double start_azimuth, double direction, int begin, int end, Cloud& full)
{
  // Points are in firing order within a ring: the azimuth turned since the sweep start, step by step.
  const auto& azimuth = scratch_.azimuths;
  double progress = 0.0;  // radians turned since the sweep start
  for (int k = begin; k < end; ++k)
  {
    if (k == begin)
    {
      progress = wrapFrom(direction * (double(azimuth[k]) - start_azimuth), -kRingStartLead);
    }
    else
    {
      progress += direction * wrapFrom(double(azimuth[k]) - azimuth[k - 1], -M_PI);
      // Past a full turn: the ring's returns came in two blocks (two lasers that share a nominal
      // ring, as in KITTI's calibrated HDL-64); the second block starts over.
      if (progress > kTwoPi + kFullTurnMargin)
      {
        progress -= kTwoPi;
      }
    }
    const double fraction = std::clamp(progress / kTwoPi, 0.0, 1.0);
    full.points[k].time = static_cast<float>(fraction * config_.scan_period);
  }
}

void ScanRegistration::markUnreliable(const Cloud& full, int begin, int end, RegistrationStats& stats)
{
  const int w = config_.curvature_half_window;
  auto& picked = scratch_.picked;
  const auto& range = scratch_.range;
  auto mark = [&](int from, int to, std::size_t& counter)
  {
    for (int k = std::max(from, begin); k <= std::min(to, end - 1); ++k)
    {
      if (picked[k] != kUnreliable)
      {
        picked[k] = kUnreliable;
        ++counter;
      }
    }
  };

  for (int i = begin + w; i < end - w - 1; ++i)
  {
    const Point& a = full.points[i];
    const Point& b = full.points[i + 1];
    const float gap_next = squaredGap(a, b);
    if (config_.reject_occluded && gap_next > config_.occlusion_gap_sq)
    {
      const float ra = range[i], rb = range[i + 1];
      // Chord between the two unit bearings: about the angle between the beams.
      const float dx = a.x / ra - b.x / rb, dy = a.y / ra - b.y / rb, dz = a.z / ra - b.z / rb;
      const float bearing = std::sqrt(dx * dx + dy * dy + dz * dz);
      const float tolerance = static_cast<float>(config_.occlusion_continuity);
      const float cap = static_cast<float>(config_.occlusion_continuity_cap);
      if (bearing < config_.occlusion_max_bearing)
      {
        const bool continuous = tolerance > 0.0f && gapIsContinuous(full, i, begin, end, tolerance, cap);
        const int from = ra > rb ? i - w : i + 1;  // the far side: a lies behind b's edge, or b behind a's
        if (!continuous)
        {
          mark(from, from + w, stats.occluded);
        }
        else if (config_.occlusion_straight_tolerance > 0.0)
        {
          for (int k = std::max(from, begin); k <= std::min(from + w, end - 1); ++k)
          {
            if (picked[k] == kFree && windowIsStraight(full, k, w, begin, end, config_.occlusion_straight_tolerance))
            {
              picked[k] = kNoEdge;
            }
          }
        }
      }
    }
    if (config_.reject_grazing)
    {
      const float gap_prev = squaredGap(a, full.points[i - 1]);
      const float limit = static_cast<float>(config_.grazing_gap_ratio_sq) * range[i] * range[i];
      if (gap_next > limit && gap_prev > limit)
      {
        mark(i, i, stats.grazing);
      }
    }
  }
}

void ScanRegistration::suppressNeighbours(const Cloud& full, int index, int ring_begin, int ring_end)
{
  auto& picked = scratch_.picked;
  const int w = config_.curvature_half_window;
  for (int l = 1; l <= w && index + l < ring_end; ++l)
  {
    if (squaredGap(full.points[index + l], full.points[index + l - 1]) > config_.suppression_gap_sq)
    {
      break;
    }
    if (picked[index + l] == kFree || picked[index + l] == kNoEdge)
    {
      picked[index + l] = kTaken;
    }
  }
  for (int l = 1; l <= w && index - l >= ring_begin; ++l)
  {
    if (squaredGap(full.points[index - l], full.points[index - l + 1]) > config_.suppression_gap_sq)
    {
      break;
    }
    if (picked[index - l] == kFree || picked[index - l] == kNoEdge)
    {
      picked[index - l] = kTaken;
    }
  }
}

void ScanRegistration::pickSector(const Cloud& full, int begin, int end, RingGroup& group)
{
  // [begin, end) lies inside one ring whose bounds are [ring_begin, ring_end).
  const int w = config_.curvature_half_window;
  const int ring_begin = begin - w;
  const int ring_end = end + w;
  const auto& curvature = scratch_.curvature;
  auto& picked = scratch_.picked;
  auto& label = scratch_.label;
  FeatureSet& out = group.features;
  const auto threshold = static_cast<float>(config_.curvature_threshold);

  // Whether edge point i bends across the ring (FeatureSet::bending): the part of its curvature vector
  // across the chord of its window passes the threshold. Every edge point stays one of odometry's.
  const auto bends = [&](int i)
  {
    const Eigen::Vector3f d = curvatureVector(full, i, w);
    const Eigen::Vector3f chord =
        (full.points[i + w].getVector3fMap() - full.points[i - w].getVector3fMap()).normalized();
    return (d - d.dot(chord) * chord).squaredNorm() > threshold;
  };
  // Edges: the free candidates above the threshold, sharpest first, ties to the lower index.
  int taken = 0;
  takeBestFirst(
      begin, end, config_.max_less_sharp_per_sector,
      [&](int i) { return curvature[i] > threshold && picked[i] == kFree; },
      // A curvature is a sum of squares, and the bits of floats >= 0 order as they do: the key is the
      // curvature's bits above the complemented index, so that the larger key is the one taken first.
      [&](int i) { return sortKey(curvature[i], ~static_cast<std::uint32_t>(i)); },
      [&](int i)
      {
        if (picked[i] != kFree)
        {
          return false;
        }
        const bool sharp = ++taken <= config_.max_sharp_per_sector;
        label[i] = sharp ? kSharp : kLessSharp;
        if (sharp)
        {
          out.sharp.push_back(full.points[i]);
        }
        out.less_sharp.push_back(full.points[i]);
        if (out.bending && bends(i))
        {
          out.bending->push_back(full.points[i]);
        }
        picked[i] = kTaken;
        suppressNeighbours(full, i, ring_begin, ring_end);
        return true;
      });

  // Planes: the free candidates below the threshold, flattest first, ties to the lower index.
  takeBestFirst(
      begin, end, config_.max_flat_per_sector,
      [&](int i) { return curvature[i] < threshold && (picked[i] == kFree || picked[i] == kNoEdge); },
      // Complemented as a whole: the flattest has the largest key, ties still to the lower index.
      [&](int i) { return ~sortKey(curvature[i], static_cast<std::uint32_t>(i)); },
      [&](int i)
      {
        if (picked[i] != kFree && picked[i] != kNoEdge)
        {
          return false;
        }
        label[i] = kFlat;
        out.flat.push_back(full.points[i]);
        picked[i] = kTaken;
        suppressNeighbours(full, i, ring_begin, ring_end);
        return true;
      });

  for (int i = begin; i < end; ++i)
  {
    if (label[i] <= kPlain)
    {
      group.less_flat_ring.push_back(full.points[i]);
    }
  }
}

void ScanRegistration::extractRings(Cloud& full, const std::vector<int>& ring_begin, int first_ring, int end_ring,
                                    const SweepStart* sweep_start, RingGroup& group)
{
  const int w = config_.curvature_half_window;
  const int min_ring_points = 2 * w + 1 + config_.sectors;
  for (int r = first_ring; r < end_ring; ++r)
  {
    const int begin = ring_begin[r];
    const int end = ring_begin[r + 1];
    if (sweep_start != nullptr)
    {
      timesFromAzimuth(sweep_start->azimuth, sweep_start->direction, begin, end, full);
    }
    for (int i = begin; i < end; ++i)
    {
      const Point& p = full.points[i];
      scratch_.range[i] = std::sqrt(p.x * p.x + p.y * p.y + p.z * p.z);
      scratch_.curvature[i] = 0.0f;
      scratch_.picked[i] = kFree;
      scratch_.label[i] = kPlain;
    }
    if (end - begin < min_ring_points)
    {
      continue;
    }
    for (int i = begin + w; i < end - w; ++i)
    {
      scratch_.curvature[i] = curvatureVector(full, i, w).squaredNorm();
    }
    markUnreliable(full, begin, end, group.stats);

    group.less_flat_ring.clear();
    const int first = begin + w;
    const int span = (end - w) - first;
    for (int s = 0; s < config_.sectors; ++s)
    {
      const int sp = first + span * s / config_.sectors;
      const int ep = first + span * (s + 1) / config_.sectors;
      if (ep > sp)
      {
        pickSector(full, sp, ep, group);
      }
    }
    voxelDownsample(group.less_flat_ring, config_.less_flat_leaf_size, group.features.less_flat);
  }
}

bool ScanRegistration::process(const Cloud& cloud, double stamp, bool has_ring, bool has_time, FeatureSet& out)
{
  out.stamp = stamp;
  out.scan_period = config_.scan_period;
  out.has_time = true;
  out.stats = RegistrationStats{};
  for (Cloud* c : { &out.sharp, &out.less_sharp, &out.flat, &out.less_flat, &out.full })
  {
    c->clear();
  }
  resetBending(out, config_.curvature_across_ring);
  RegistrationStats& stats = out.stats;
  stats.points_in = cloud.size();

  // Sort the points into rings, the input split over the threads in contiguous blocks; the blocks then
  // join ring by ring in input order, as one thread would have produced them.
  const bool ring_from_field = has_ring && config_.use_ring_field;
  const bool time_from_field = has_time && config_.use_time_field;
  const int parts =
      cloud.size() < static_cast<std::size_t>(kMinPointsForThreads) ? 1 : std::clamp(config_.threads, 1, kMaxThreads);
  blocks_.resize(static_cast<std::size_t>(parts));
  for (InputBlock& block : blocks_)
  {
    block.stats = RegistrationStats{};
  }
  executor_->parallelChunks(static_cast<int>(cloud.size()), parts, 1,
                            [&](int begin, int end, int part)
                            { bucketByRing(cloud, begin, end, ring_from_field, time_from_field, blocks_[part]); });
  double start_azimuth = 0.0;
  bool have_start = false;
  for (const InputBlock& block : blocks_)
  {
    stats.invalid += block.stats.invalid;
    stats.out_of_range += block.stats.out_of_range;
    stats.unassigned_ring += block.stats.unassigned_ring;
    if (!have_start && block.have_start)
    {
      have_start = true;
      start_azimuth = block.start_azimuth;
    }
  }
  std::vector<int> ring_begin;
  gatherRings(time_from_field, out.full, ring_begin);
  const int rings = static_cast<int>(ring_begin.size()) - 1;
  for (int r = 0; r < rings; ++r)
  {
    stats.rings += ring_begin[r + 1] > ring_begin[r] ? 1 : 0;
  }
  stats.points_used = out.full.size();

  const int w = config_.curvature_half_window;
  const int min_ring_points = 2 * w + 1 + config_.sectors;
  if (static_cast<int>(out.full.size()) < min_ring_points)
  {
    out.full.clear();
    return false;
  }
  // Without a time field, time follows the azimuth; the spin direction comes from the data: the sum of
  // azimuth steps along the rings. Velodyne drivers spin clockwise seen from above; KITTI stores its
  // sweeps the other way.
  SweepStart sweep_start;
  if (!time_from_field)
  {
    const double turn = std::accumulate(scratch_.ring_turn.begin(), scratch_.ring_turn.end(), 0.0);
    sweep_start = SweepStart{ start_azimuth, turn >= 0.0 ? 1.0 : -1.0 };
  }

  const std::size_t n = out.full.size();
  scratch_.curvature.resize(n);
  scratch_.range.resize(n);
  scratch_.picked.resize(n);
  scratch_.label.resize(n);

  // Rings are independent from here on: groups of consecutive rings go to whichever thread is free, and
  // their features join in ring order (the result does not depend on the grouping).
  const int groups = Executor::effectiveParts(rings, config_.threads * kChunksPerThread, 1);
  groups_.resize(static_cast<std::size_t>(std::max(groups, 1)));
  for (RingGroup& group : groups_)
  {
    for (Cloud* c :
         { &group.features.sharp, &group.features.less_sharp, &group.features.flat, &group.features.less_flat })
    {
      c->clear();
    }
    resetBending(group.features, config_.curvature_across_ring);
    group.stats = RegistrationStats{};
  }
  executor_->parallelChunks(
      rings, groups, 1,
      [&](int first, int last, int group)
      { extractRings(out.full, ring_begin, first, last, time_from_field ? nullptr : &sweep_start, groups_[group]); });
  for (const RingGroup& group : groups_)
  {
    const FeatureSet& f = group.features;
    out.sharp.points.insert(out.sharp.points.end(), f.sharp.points.begin(), f.sharp.points.end());
    out.less_sharp.points.insert(out.less_sharp.points.end(), f.less_sharp.points.begin(), f.less_sharp.points.end());
    out.flat.points.insert(out.flat.points.end(), f.flat.points.begin(), f.flat.points.end());
    out.less_flat.points.insert(out.less_flat.points.end(), f.less_flat.points.begin(), f.less_flat.points.end());
    if (out.bending)
    {
      out.bending->points.insert(out.bending->points.end(), f.bending->points.begin(), f.bending->points.end());
    }
    stats.occluded += group.stats.occluded;
    stats.grazing += group.stats.grazing;
  }

  for (Cloud* c : { &out.sharp, &out.less_sharp, &out.flat, &out.less_flat })
  {
    setUnorganized(*c);
  }
  if (out.bending)
  {
    setUnorganized(*out.bending);
  }
  return true;
}

}  // namespace aloam
