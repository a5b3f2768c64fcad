#include "aloam_nodelet/ros/pointcloud2_reader.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <limits>
#include <vector>

#include <sensor_msgs/PointField.h>

namespace aloam
{
namespace ros_io
{
namespace
{
using sensor_msgs::PointField;

constexpr double kNanosecondsToSeconds = 1e-9;
constexpr double kSecondsToSeconds = 1.0;
constexpr double kMaxTimeSpanInScanPeriods = 2.0;
constexpr double kMaxRing = std::numeric_limits<std::uint16_t>::max();
constexpr std::uint64_t kNanosecondsPerMicrosecond = 1000;
constexpr std::size_t kMaxScalarSize = 8;
// Fewer points than this per thread are not worth handing to a second thread.
constexpr int kMinPointsPerPart = 16384;

/// Where a used field sits inside one point.
struct FieldSlot
{
  bool present = false;
  std::uint32_t offset = 0;
  std::uint8_t datatype = 0;
};

/// What an optional field's datatype may be.
enum class TypeRequirement
{
  kAnyNumeric,
  kInteger,
};

/// A per-point time field the reader understands, and the unit its values are in.
struct TimeFieldKind
{
  const char* name;
  double to_seconds;
};

constexpr TimeFieldKind kTimeFieldKinds[] = {
  { "time", kSecondsToSeconds },       // Velodyne: float32 seconds, relative to first or last point
  { "t", kNanosecondsToSeconds },      // Ouster: uint32 nanoseconds since the sweep start
  { "timestamp", kSecondsToSeconds },  // Hesai, RoboSense: float64 absolute seconds
};

bool hostIsBigEndian()
{
#if defined(__BYTE_ORDER__) && defined(__ORDER_BIG_ENDIAN__)
  return __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__;
#else
  const std::uint16_t probe = 1;
  std::uint8_t first_byte = 0;
  std::memcpy(&first_byte, &probe, 1);
  return first_byte == 0;
#endif
}

bool isFloatType(std::uint8_t datatype)
{
  return datatype == PointField::FLOAT32 || datatype == PointField::FLOAT64;
}

std::string quoteName(const std::string& name)
{
  return "'" + name + "'";
}

std::string formatNumber(double value)
{
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.6g", value);
  return buffer;
}

/// Reads one scalar of type T from possibly unaligned memory, reversing its bytes if kSwap.
template <typename T, bool kSwap>
T loadScalar(const std::uint8_t* src)
{
  static_assert(sizeof(T) <= kMaxScalarSize, "scalar too large");
  std::uint8_t bytes[sizeof(T)];
  std::memcpy(bytes, src, sizeof(T));
  if (kSwap)
  {
    std::reverse(bytes, bytes + sizeof(T));
  }
  T value;
  std::memcpy(&value, bytes, sizeof(T));
  return value;
}

/// Reads a scalar of any PointField datatype as a double. The datatype was validated beforehand.
template <bool kSwap>
double loadAnyAsDouble(const std::uint8_t* src, std::uint8_t datatype)
{
  switch (datatype)
  {
    case PointField::FLOAT32:
      return loadScalar<float, kSwap>(src);
    case PointField::FLOAT64:
      return loadScalar<double, kSwap>(src);
    case PointField::UINT8:
      return loadScalar<std::uint8_t, kSwap>(src);
    case PointField::INT8:
      return loadScalar<std::int8_t, kSwap>(src);
    case PointField::UINT16:
      return loadScalar<std::uint16_t, kSwap>(src);
    case PointField::INT16:
      return loadScalar<std::int16_t, kSwap>(src);
    case PointField::UINT32:
      return loadScalar<std::uint32_t, kSwap>(src);
    case PointField::INT32:
      return loadScalar<std::int32_t, kSwap>(src);
    default:
      return 0.0;
  }
}

/// loadAnyAsDouble with the common datatypes inlined.
template <bool kSwap>
inline double loadAsDouble(const std::uint8_t* src, std::uint8_t datatype)
{
  if (datatype == PointField::FLOAT32)
  {
    return loadScalar<float, kSwap>(src);
  }
  if (datatype == PointField::UINT16)
  {
    return loadScalar<std::uint16_t, kSwap>(src);
  }
  if (datatype == PointField::UINT32)
  {
    return loadScalar<std::uint32_t, kSwap>(src);
  }
  return loadAnyAsDouble<kSwap>(src, datatype);
}

/// Coordinates are FLOAT32 or FLOAT64 (validated beforehand).
template <bool kSwap>
float loadCoordinate(const std::uint8_t* src, std::uint8_t datatype)
{
  if (datatype == PointField::FLOAT32)
  {
    return loadScalar<float, kSwap>(src);
  }
  return static_cast<float>(loadScalar<double, kSwap>(src));
}

const PointField* findField(const sensor_msgs::PointCloud2& msg, const std::string& name)
{
  for (const PointField& field : msg.fields)
  {
    if (field.name == name)
    {
      return &field;
    }
  }
  return nullptr;
}

/// Checks a present field's datatype, extent and count. On a problem returns its description (the
/// caller makes it an error or a warning); count != 1 is tolerated with a warning.
std::string checkField(const PointField& field, std::uint32_t point_step, bool require_float,
                       TypeRequirement requirement, std::vector<std::string>& warnings)
{
  const std::size_t size = pointFieldSize(field.datatype);
  if (size == 0)
  {
    return "field " + quoteName(field.name) + " has unknown datatype code " + std::to_string(field.datatype);
  }
  if (require_float && !isFloatType(field.datatype))
  {
    return "field " + quoteName(field.name) + " has datatype " + std::to_string(field.datatype) +
           ", expected FLOAT32 (7) or FLOAT64 (8)";
  }
  if (requirement == TypeRequirement::kInteger && isFloatType(field.datatype))
  {
    return "field " + quoteName(field.name) + " has floating-point datatype " + std::to_string(field.datatype) +
           ", expected an integer type";
  }
  const std::uint64_t end = static_cast<std::uint64_t>(field.offset) + size;
  if (end > point_step)
  {
    return "field " + quoteName(field.name) + " (offset " + std::to_string(field.offset) + ", " + std::to_string(size) +
           " bytes) extends beyond point_step " + std::to_string(point_step);
  }
  if (field.count != 1)
  {
    warnings.push_back("Field " + quoteName(field.name) + " has count " + std::to_string(field.count) +
                       "; its first element is used.");
  }
  return {};
}

/// Resolves a required coordinate field; returns false and sets `error` when it is unusable.
bool resolveCoordinate(const sensor_msgs::PointCloud2& msg, const std::string& name, FieldSlot& slot,
                       std::string& error, std::vector<std::string>& warnings)
{
  const PointField* field = findField(msg, name);
  if (field == nullptr)
  {
    error = "required field " + quoteName(name) + " is missing";
    return false;
  }
  const std::string problem = checkField(*field, msg.point_step, true, TypeRequirement::kAnyNumeric, warnings);
  if (!problem.empty())
  {
    error = problem;
    return false;
  }
  slot = { true, field->offset, field->datatype };
  return true;
}

/// Resolves an optional field that is present; an unusable one is ignored with a warning.
FieldSlot resolveOptional(const sensor_msgs::PointCloud2& msg, const PointField& field, TypeRequirement requirement,
                          std::vector<std::string>& warnings)
{
  const std::string problem = checkField(field, msg.point_step, false, requirement, warnings);
  if (!problem.empty())
  {
    warnings.push_back("Ignoring " + problem + ".");
    return {};
  }
  return { true, field.offset, field.datatype };
}

/// Row stride to use and how many complete points the data buffer holds.
struct Layout
{
  std::uint64_t row_step = 0;
  std::uint64_t complete_points = 0;
};

/// Validates row_step and the buffer size against width, height and point_step (point_step > 0 and
/// width * height > 0 are guaranteed by the caller). Overflow-safe for any header values.
Layout computeLayout(const sensor_msgs::PointCloud2& msg, std::vector<std::string>& warnings)
{
  const std::uint64_t width = msg.width;
  const std::uint64_t height = msg.height;
  const std::uint64_t point_step = msg.point_step;
  const std::uint64_t data_size = msg.data.size();
  const std::uint64_t declared = width * height;
  const std::uint64_t dense_row = width * point_step;  // < 2^64: both factors < 2^32

  Layout layout;
  layout.row_step = msg.row_step;
  if (layout.row_step < dense_row)
  {
    warnings.push_back("row_step " + std::to_string(msg.row_step) + " is smaller than width*point_step " +
                       std::to_string(dense_row) + "; assuming unpadded rows.");
    layout.row_step = dense_row;
  }

  if (data_size < dense_row)
  {
    // Not even the first row is complete.
    layout.complete_points = std::min(width, data_size / point_step);
  }
  else
  {
    const std::uint64_t rows_that_fit = (data_size - dense_row) / layout.row_step + 1;
    if (rows_that_fit >= height)
    {
      layout.complete_points = declared;
    }
    else
    {
      // The next row starts beyond the data when the data ends inside a row's padding.
      const std::uint64_t partial_row_begin = rows_that_fit * layout.row_step;
      const std::uint64_t partial =
          partial_row_begin < data_size ? std::min(width, (data_size - partial_row_begin) / point_step) : 0;
      layout.complete_points = rows_that_fit * width + partial;
    }
  }

  if (layout.complete_points == declared)
  {
    // Every point is present; only the padding after the last row may be missing.
    if (data_size / layout.row_step < height)  // i.e. data_size < row_step * height, without overflow
    {
      warnings.push_back("Data holds " + std::to_string(data_size) +
                         " bytes, less than row_step*height; the last row's padding is missing but every point "
                         "is present.");
    }
  }
  else if (layout.complete_points > 0)
  {
    warnings.push_back("Data holds only " + std::to_string(data_size) + " bytes for " + std::to_string(declared) +
                       " declared points; read the " + std::to_string(layout.complete_points) + " complete points.");
  }
  return layout;
}

/// Everything the per-point loop needs, resolved once per message.
struct DecodePlan
{
  FieldSlot x;
  FieldSlot y;
  FieldSlot z;
  FieldSlot intensity;
  FieldSlot ring;
  FieldSlot time;
  double time_to_seconds = kSecondsToSeconds;
  std::uint64_t width = 0;
  std::uint64_t point_step = 0;
  std::uint64_t row_step = 0;
  std::uint64_t complete_points = 0;  // the data holds at least this many whole points
  std::uint64_t cap = 0;              // keep at most this many valid points
};

/// What the per-point loop found besides the points themselves.
struct DecodeStats
{
  std::uint64_t points_read = 0;
  std::size_t kept = 0;  // valid points written
  std::size_t dropped_invalid = 0;
  std::size_t rings_clamped = 0;
  bool times_finite = true;
  float min_time = 0.0f;  // extremes of the stored, reference-relative finite times
  float max_time = 0.0f;
  bool have_time = false;  // min_time / max_time hold a time
  bool capped = false;

  /// Adds the stats of the next stretch of points.
  void add(const DecodeStats& o)
  {
    points_read += o.points_read;
    kept += o.kept;
    dropped_invalid += o.dropped_invalid;
    rings_clamped += o.rings_clamped;
    times_finite = times_finite && o.times_finite;
    if (o.have_time)
    {
      min_time = have_time ? std::min(min_time, o.min_time) : o.min_time;
      max_time = have_time ? std::max(max_time, o.max_time) : o.max_time;
      have_time = true;
    }
    capped = capped || o.capped;
  }
};

template <bool kSwap>
bool validCoordinates(const std::uint8_t* point, const DecodePlan& plan, aloam::Point& p)
{
  p.x = loadCoordinate<kSwap>(point + plan.x.offset, plan.x.datatype);
  p.y = loadCoordinate<kSwap>(point + plan.y.offset, plan.y.datatype);
  p.z = loadCoordinate<kSwap>(point + plan.z.offset, plan.z.datatype);
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && !(p.x == 0.0f && p.y == 0.0f && p.z == 0.0f);
}

const std::uint8_t* pointAt(const std::uint8_t* data, const DecodePlan& plan, std::uint64_t k)
{
  return data + (k / plan.width) * plan.row_step + (k % plan.width) * plan.point_step;
}

/// The raw time (seconds) of the first valid point with a finite time: stored times are relative to it,
/// so that absolute stamps keep their precision in a float. 0 if there is none.
template <bool kSwap>
double timeReference(const std::uint8_t* data, const DecodePlan& plan)
{
  for (std::uint64_t k = 0; plan.time.present && k < plan.complete_points; ++k)
  {
    const std::uint8_t* point = pointAt(data, plan, k);
    aloam::Point p;
    if (validCoordinates<kSwap>(point, plan, p))
    {
      const double seconds = loadAsDouble<kSwap>(point + plan.time.offset, plan.time.datatype) * plan.time_to_seconds;
      if (std::isfinite(seconds))
      {
        return seconds;
      }
    }
  }
  return 0.0;
}

/// Decodes points [begin, end) of the data, writing the valid ones to out[0, ...) (room for end - begin
/// points), at most `cap` of them.
template <bool kSwap>
DecodeStats decodePoints(const std::uint8_t* data, const DecodePlan& plan, std::uint64_t begin, std::uint64_t end,
                         std::size_t cap, double time_reference, aloam::Point* out)
{
  DecodeStats stats;
  std::uint64_t column = begin % plan.width;
  const std::uint8_t* point = pointAt(data, plan, begin);
  for (std::uint64_t k = begin; k < end; ++k, point += plan.point_step)
  {
    if (column == plan.width)  // the next row (rows may be padded)
    {
      column = 0;
      point = pointAt(data, plan, k);
    }
    ++column;
    if (stats.kept >= cap)
    {
      stats.capped = true;
      break;
    }
    ++stats.points_read;
    aloam::Point& p = out[stats.kept];
    if (!validCoordinates<kSwap>(point, plan, p))
    {
      ++stats.dropped_invalid;
      continue;
    }
    p.data[3] = 1.0f;
    p.intensity = 0.0f;
    if (plan.intensity.present)
    {
      p.intensity = static_cast<float>(loadAsDouble<kSwap>(point + plan.intensity.offset, plan.intensity.datatype));
    }
    p.ring = 0;
    if (plan.ring.present)
    {
      const double ring = loadAsDouble<kSwap>(point + plan.ring.offset, plan.ring.datatype);
      if (ring < 0.0 || ring > kMaxRing)
      {
        ++stats.rings_clamped;
      }
      p.ring = static_cast<std::uint16_t>(std::clamp(ring, 0.0, kMaxRing));
    }
    p.time = 0.0f;
    if (plan.time.present)
    {
      const double seconds = loadAsDouble<kSwap>(point + plan.time.offset, plan.time.datatype) * plan.time_to_seconds;
      if (!std::isfinite(seconds))
      {
        stats.times_finite = false;
      }
      p.time = static_cast<float>(seconds - time_reference);
      if (!std::isnan(p.time))  // an infinite time makes the span infinite: times are then dropped
      {
        stats.min_time = stats.have_time ? std::min(stats.min_time, p.time) : p.time;
        stats.max_time = stats.have_time ? std::max(stats.max_time, p.time) : p.time;
        stats.have_time = true;
      }
    }
    ++stats.kept;
  }
  return stats;
}

/// Decodes every complete point into `out` (resized to the points kept), in contiguous stretches, one per
/// thread of `executor` (when given and the cloud is large), then joined in order: the result does not
/// depend on the threads. With a cap the data may exceed, in one stretch (the cap keeps the first valid
/// points). Two stretches read a KITTI sweep in about 60 % of the time of one (docs/performance.md).
template <bool kSwap>
DecodeStats decodeAll(const std::uint8_t* data, const DecodePlan& plan, double time_reference,
                      aloam::Executor* executor, aloam::Cloud& out)
{
  const std::uint64_t n = plan.complete_points;
  const int parts =
      executor != nullptr && plan.cap >= n && n <= static_cast<std::uint64_t>(std::numeric_limits<int>::max())
          ? aloam::Executor::effectiveParts(static_cast<int>(n), executor->threads(), kMinPointsPerPart)
          : 1;
  out.points.resize(static_cast<std::size_t>(std::min(n, plan.cap)));
  std::vector<DecodeStats> part_stats(static_cast<std::size_t>(parts));
  const auto bound = [&](int part) { return n * static_cast<std::uint64_t>(part) / static_cast<std::uint64_t>(parts); };
  aloam::parallelChunks(parts > 1 ? executor : nullptr, parts, parts, 1,
                        [&](int first, int last, int)
                        {
                          for (int part = first; part < last; ++part)
                          {
                            part_stats[part] = decodePoints<kSwap>(data, plan, bound(part), bound(part + 1), plan.cap,
                                                                   time_reference, out.points.data() + bound(part));
                          }
                        });
  DecodeStats stats;
  for (int part = 0; part < parts; ++part)
  {
    // Close the gap the dropped points of the stretches before left.
    if (stats.kept != bound(part) && part_stats[part].kept > 0)
    {
      std::memmove(out.points.data() + stats.kept, out.points.data() + bound(part),
                   part_stats[part].kept * sizeof(aloam::Point));
    }
    stats.add(part_stats[part]);
  }
  out.points.resize(stats.kept);
  return stats;
}

/// Shifts the stored (reference-relative) times so the earliest is 0, or zeroes them when unusable.
void finishTimes(const DecodeStats& stats, double time_reference, const ReaderOptions& options, aloam::Cloud& out,
                 ReadReport& report)
{
  if (out.points.empty())
  {
    report.time_field.clear();
    return;
  }
  const double span = static_cast<double>(stats.max_time) - static_cast<double>(stats.min_time);
  const double max_span = kMaxTimeSpanInScanPeriods * options.scan_period;
  bool usable = true;
  if (!stats.times_finite || !std::isfinite(span))
  {
    report.warnings.push_back("Time field " + quoteName(report.time_field) +
                              " has non-finite values; per-point time disabled (set to 0).");
    usable = false;
  }
  else if (!(options.scan_period > 0.0))
  {
    report.warnings.push_back("scan_period " + formatNumber(options.scan_period) +
                              " is not positive; the time span was not checked.");
  }
  else if (span == 0.0 && out.points.size() > 1)
  {
    report.warnings.push_back("Time field " + quoteName(report.time_field) +
                              " has the same value for every point; per-point time disabled (set to 0).");
    usable = false;
  }
  else if (span > max_span)
  {
    report.warnings.push_back("Time field " + quoteName(report.time_field) + " spans " + formatNumber(span) +
                              " s, more than 2*scan_period (" + formatNumber(max_span) +
                              " s); per-point time disabled (set to 0).");
    usable = false;
  }

  if (!usable)
  {
    for (auto& point : out.points)
    {
      point.time = 0.0f;
    }
    report.time_field.clear();
    return;
  }
  if (stats.min_time != 0.0f)  // usually 0 already: times relative to the first point, or Ouster's t
  {
    for (auto& point : out.points)
    {
      point.time -= stats.min_time;
    }
  }
  report.has_time = true;
  report.time_origin = time_reference + static_cast<double>(stats.min_time);
}

ReadReport readUnchecked(const sensor_msgs::PointCloud2& msg, const ReaderOptions& options, aloam::Cloud& out)
{
  ReadReport report;
  report.points_in = static_cast<std::size_t>(static_cast<std::uint64_t>(msg.width) * msg.height);

  out.header.frame_id = msg.header.frame_id;
  out.header.stamp = msg.header.stamp.toNSec() / kNanosecondsPerMicrosecond;
  out.header.seq = msg.header.seq;
  if (msg.header.frame_id.empty())
  {
    report.warnings.push_back("header.frame_id is empty.");
  }

  if (report.points_in == 0)
  {
    report.error = "empty cloud (width " + std::to_string(msg.width) + ", height " + std::to_string(msg.height) + ")";
    return report;
  }

  // Fields. Coordinates first: they decide whether the cloud is usable at all (and guarantee
  // point_step > 0, which the layout computation divides by).
  FieldSlot x_slot;
  FieldSlot y_slot;
  FieldSlot z_slot;
  if (!resolveCoordinate(msg, "x", x_slot, report.error, report.warnings) ||
      !resolveCoordinate(msg, "y", y_slot, report.error, report.warnings) ||
      !resolveCoordinate(msg, "z", z_slot, report.error, report.warnings))
  {
    return report;
  }

  FieldSlot intensity_slot;
  if (const PointField* field = findField(msg, "intensity"))
  {
    intensity_slot = resolveOptional(msg, *field, TypeRequirement::kAnyNumeric, report.warnings);
  }
  else
  {
    report.warnings.push_back("No 'intensity' field; intensity set to 0.");
  }

  FieldSlot ring_slot;
  if (const PointField* field = findField(msg, "ring"))
  {
    ring_slot = resolveOptional(msg, *field, TypeRequirement::kInteger, report.warnings);
  }
  report.has_ring = ring_slot.present;

  FieldSlot time_slot;
  double time_to_seconds = kSecondsToSeconds;
  for (const TimeFieldKind& kind : kTimeFieldKinds)
  {
    if (const PointField* field = findField(msg, kind.name))
    {
      time_slot = resolveOptional(msg, *field, TypeRequirement::kAnyNumeric, report.warnings);
      if (time_slot.present)
      {
        time_to_seconds = kind.to_seconds;
        report.time_field = kind.name;
        break;
      }
    }
  }

  // Layout.
  const Layout layout = computeLayout(msg, report.warnings);
  if (layout.complete_points == 0)
  {
    report.error = "data (" + std::to_string(msg.data.size()) + " bytes) holds no complete point (point_step " +
                   std::to_string(msg.point_step) + ")";
    return report;
  }

  DecodePlan plan;
  plan.x = x_slot;
  plan.y = y_slot;
  plan.z = z_slot;
  plan.intensity = intensity_slot;
  plan.ring = ring_slot;
  plan.time = time_slot;
  plan.time_to_seconds = time_to_seconds;
  plan.width = msg.width;
  plan.point_step = msg.point_step;
  plan.row_step = layout.row_step;
  plan.complete_points = layout.complete_points;
  plan.cap = options.max_points == 0 ? layout.complete_points : options.max_points;

  const bool swap_bytes = static_cast<bool>(msg.is_bigendian) != hostIsBigEndian();
  const std::uint8_t* data = msg.data.data();
  const double time_reference = swap_bytes ? timeReference<true>(data, plan) : timeReference<false>(data, plan);
  const DecodeStats stats = swap_bytes ? decodeAll<true>(data, plan, time_reference, options.executor, out)
                                       : decodeAll<false>(data, plan, time_reference, options.executor, out);
  report.dropped_invalid = stats.dropped_invalid;

  if (stats.capped)
  {
    report.warnings.push_back("Cloud exceeds max_points (" + std::to_string(plan.cap) + "); kept the first " +
                              std::to_string(plan.cap) + " valid points and left " +
                              std::to_string(plan.complete_points - stats.points_read) + " points unread.");
  }
  if (stats.rings_clamped > 0)
  {
    report.warnings.push_back(std::to_string(stats.rings_clamped) + " ring values outside [0, 65535] were clamped.");
  }
  if (time_slot.present)
  {
    finishTimes(stats, time_reference, options, out, report);
  }

  out.width = static_cast<std::uint32_t>(out.points.size());
  out.height = 1;
  out.is_dense = true;
  report.points_out = out.points.size();
  if (report.points_out == 0)
  {
    report.error = "no valid points (" + std::to_string(report.dropped_invalid) + " dropped for NaN/Inf or zero xyz)";
    return report;
  }
  report.ok = true;
  return report;
}
}  // namespace

std::size_t pointFieldSize(std::uint8_t datatype)
{
  switch (datatype)
  {
    case PointField::INT8:
    case PointField::UINT8:
      return 1;
    case PointField::INT16:
    case PointField::UINT16:
      return 2;
    case PointField::INT32:
    case PointField::UINT32:
    case PointField::FLOAT32:
      return 4;
    case PointField::FLOAT64:
      return 8;
    default:
      return 0;
  }
}

ReadReport readPointCloud2(const sensor_msgs::PointCloud2& msg, const ReaderOptions& options, aloam::Cloud& out)
{
  // The points stay until the decode overwrites them: resizing zero-fills only what the cloud grows by
  // (a reused cloud, sweep after sweep, hardly at all).
  out.width = 0;
  out.height = 1;
  out.is_dense = true;
  try
  {
    ReadReport report = readUnchecked(msg, options, out);
    if (!report.ok)
    {
      out.points.clear();
    }
    return report;
  }
  catch (const std::exception& e)
  {
    out.points.clear();
    out.width = 0;
    ReadReport report;
    report.points_in = static_cast<std::size_t>(static_cast<std::uint64_t>(msg.width) * msg.height);
    report.error = std::string("conversion failed: ") + e.what();
    return report;
  }
  catch (...)
  {
    out.points.clear();
    out.width = 0;
    ReadReport report;
    report.error = "conversion failed: unknown exception";
    return report;
  }
}

}  // namespace ros_io
}  // namespace aloam
