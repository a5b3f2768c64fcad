// Tests for the PointCloud2 -> aloam::Cloud reader. Messages are built by hand; no ROS master needed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "aloam_nodelet/ros/pointcloud2_reader.h"

namespace
{
using aloam::ros_io::ReaderOptions;
using aloam::ros_io::readPointCloud2;
using aloam::ros_io::ReadReport;
using sensor_msgs::PointField;

constexpr std::uint8_t kFillByte = 0x42;  // unused bytes decode to plausible numbers (0x42424242 = 48.56f)
constexpr std::uint8_t kUnknownDatatype = 42;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

struct FieldDef
{
  std::string name;
  std::uint8_t datatype;
  std::uint32_t offset;
  std::uint32_t count = 1;
};

using PointValues = std::vector<double>;  // one value per FieldDef, in the same order

bool hostIsLittleEndian()
{
  const std::uint16_t probe = 1;
  std::uint8_t first_byte = 0;
  std::memcpy(&first_byte, &probe, 1);
  return first_byte == 1;
}

template <typename T>
void storeAs(std::uint8_t* dst, double value, bool big_endian)
{
  const T typed = static_cast<T>(value);
  std::uint8_t bytes[sizeof(T)];
  std::memcpy(bytes, &typed, sizeof(T));
  if (big_endian == hostIsLittleEndian())
  {
    std::reverse(bytes, bytes + sizeof(T));
  }
  std::memcpy(dst, bytes, sizeof(T));
}

void writeValue(std::uint8_t* dst, std::uint8_t datatype, double value, bool big_endian)
{
  switch (datatype)
  {
    case PointField::INT8:
      storeAs<std::int8_t>(dst, value, big_endian);
      break;
    case PointField::UINT8:
      storeAs<std::uint8_t>(dst, value, big_endian);
      break;
    case PointField::INT16:
      storeAs<std::int16_t>(dst, value, big_endian);
      break;
    case PointField::UINT16:
      storeAs<std::uint16_t>(dst, value, big_endian);
      break;
    case PointField::INT32:
      storeAs<std::int32_t>(dst, value, big_endian);
      break;
    case PointField::UINT32:
      storeAs<std::uint32_t>(dst, value, big_endian);
      break;
    case PointField::FLOAT32:
      storeAs<float>(dst, value, big_endian);
      break;
    case PointField::FLOAT64:
      storeAs<double>(dst, value, big_endian);
      break;
    default:
      break;  // unknown datatype: leave the fill bytes
  }
}

struct CloudSpec
{
  std::vector<FieldDef> fields;
  std::uint32_t point_step = 0;
  std::uint32_t width = 0;
  std::uint32_t height = 1;
  std::uint32_t row_padding = 0;
  bool big_endian = false;
};

/// Builds a message; points are laid out row by row; missing points stay as fill bytes.
sensor_msgs::PointCloud2 makeCloud(const CloudSpec& spec, const std::vector<PointValues>& points)
{
  sensor_msgs::PointCloud2 msg;
  msg.header.frame_id = "velodyne";
  msg.header.stamp.sec = 100;
  msg.header.stamp.nsec = 123456789;
  msg.header.seq = 7;
  msg.width = spec.width;
  msg.height = spec.height;
  msg.point_step = spec.point_step;
  msg.row_step = spec.width * spec.point_step + spec.row_padding;
  msg.is_bigendian = spec.big_endian;
  msg.is_dense = false;
  for (const FieldDef& def : spec.fields)
  {
    PointField field;
    field.name = def.name;
    field.datatype = def.datatype;
    field.offset = def.offset;
    field.count = def.count;
    msg.fields.push_back(field);
  }
  msg.data.assign(static_cast<std::size_t>(msg.row_step) * spec.height, kFillByte);
  for (std::size_t i = 0; i < points.size() && i < static_cast<std::size_t>(spec.width) * spec.height; ++i)
  {
    const std::size_t row = i / spec.width;
    const std::size_t column = i % spec.width;
    std::uint8_t* base = msg.data.data() + row * msg.row_step + column * spec.point_step;
    for (std::size_t f = 0; f < spec.fields.size() && f < points[i].size(); ++f)
    {
      const FieldDef& def = spec.fields[f];
      if (def.offset + aloam::ros_io::pointFieldSize(def.datatype) <= spec.point_step)
      {
        writeValue(base + def.offset, def.datatype, points[i][f], spec.big_endian);
      }
    }
  }
  return msg;
}

std::vector<FieldDef> xyzFields(std::uint8_t datatype = PointField::FLOAT32)
{
  const std::uint32_t size = static_cast<std::uint32_t>(aloam::ros_io::pointFieldSize(datatype));
  return { { "x", datatype, 0 }, { "y", datatype, size }, { "z", datatype, 2 * size } };
}

/// x, y, z (float32) and a float32 intensity: point_step 16.
CloudSpec xyziSpec(std::uint32_t width, std::uint32_t height = 1)
{
  CloudSpec spec;
  spec.fields = xyzFields();
  spec.fields.push_back({ "intensity", PointField::FLOAT32, 12 });
  spec.point_step = 16;
  spec.width = width;
  spec.height = height;
  return spec;
}

std::vector<PointValues> simpleXyziPoints(std::size_t n)
{
  std::vector<PointValues> points;
  for (std::size_t i = 0; i < n; ++i)
  {
    const double k = static_cast<double>(i);
    points.push_back({ 1.0 + k, -2.0 - k, 0.5 * k, 10.0 + k });
  }
  return points;
}

bool hasWarning(const ReadReport& report, const std::string& needle)
{
  return std::any_of(report.warnings.begin(), report.warnings.end(),
                     [&](const std::string& w) { return w.find(needle) != std::string::npos; });
}

std::string joinWarnings(const ReadReport& report)
{
  std::string all;
  for (const std::string& w : report.warnings)
  {
    all += "[" + w + "] ";
  }
  return all;
}

// ---------------------------------------------------------------------------------------------

TEST(PointCloud2Reader, Float32RoundTripIsExactWithUnalignedVelodyneLayout)
{
  CloudSpec spec;
  spec.fields = xyzFields();
  spec.fields.push_back({ "intensity", PointField::FLOAT32, 12 });
  spec.fields.push_back({ "ring", PointField::UINT16, 16 });
  spec.fields.push_back({ "time", PointField::FLOAT32, 18 });  // unaligned
  spec.point_step = 22;
  spec.width = 100;

  std::vector<PointValues> points;
  for (int i = 0; i < 100; ++i)
  {
    const float x = 0.37f * static_cast<float>(i) - 12.3f;
    const float y = -3.1f + 0.013f * static_cast<float>(i * i);
    const float z = 1e-3f * static_cast<float>(i) + 0.7f;
    const float intensity = 0.25f * static_cast<float>(i);
    const float time = 1e-4f * static_cast<float>(i);
    points.push_back({ x, y, z, intensity, static_cast<double>(i % 64), time });
  }
  const auto msg = makeCloud(spec, points);

  aloam::Cloud out;
  const ReadReport report = readPointCloud2(msg, ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(report.warnings.empty()) << joinWarnings(report);
  EXPECT_EQ(report.points_in, 100u);
  EXPECT_EQ(report.points_out, 100u);
  EXPECT_EQ(report.dropped_invalid, 0u);
  EXPECT_TRUE(report.has_ring);
  EXPECT_TRUE(report.has_time);
  EXPECT_EQ(report.time_field, "time");
  EXPECT_DOUBLE_EQ(report.time_origin, 0.0);
  ASSERT_EQ(out.size(), 100u);
  EXPECT_EQ(out.width, 100u);
  EXPECT_EQ(out.height, 1u);
  EXPECT_TRUE(out.is_dense);
  EXPECT_EQ(out.header.frame_id, "velodyne");
  EXPECT_EQ(out.header.stamp, 100123456u);  // microseconds
  EXPECT_EQ(out.header.seq, 7u);
  for (std::size_t i = 0; i < 100; ++i)
  {
    EXPECT_EQ(out[i].x, static_cast<float>(points[i][0])) << i;
    EXPECT_EQ(out[i].y, static_cast<float>(points[i][1])) << i;
    EXPECT_EQ(out[i].z, static_cast<float>(points[i][2])) << i;
    EXPECT_EQ(out[i].intensity, static_cast<float>(points[i][3])) << i;
    EXPECT_EQ(out[i].ring, static_cast<std::uint16_t>(points[i][4])) << i;
    EXPECT_EQ(out[i].time, static_cast<float>(points[i][5])) << i;
  }
}

TEST(PointCloud2Reader, Float64Coordinates)
{
  CloudSpec spec;
  spec.fields = xyzFields(PointField::FLOAT64);
  spec.fields.push_back({ "intensity", PointField::FLOAT32, 24 });
  spec.point_step = 28;
  spec.width = 3;
  const std::vector<PointValues> points = { { 0.1, -123.456789, 1000.5, 1.0 },
                                            { 1e-7, 2.0, -3.0, 2.0 },
                                            { 45.000001, -0.3, 7.25, 3.0 } };
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, points), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  ASSERT_EQ(out.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i)
  {
    EXPECT_EQ(out[i].x, static_cast<float>(points[i][0]));
    EXPECT_EQ(out[i].y, static_cast<float>(points[i][1]));
    EXPECT_EQ(out[i].z, static_cast<float>(points[i][2]));
    EXPECT_EQ(out[i].intensity, static_cast<float>(points[i][3]));
  }
}

struct IntensityCase
{
  std::uint8_t datatype;
  std::vector<double> values;
};

class IntensityTypes : public ::testing::TestWithParam<IntensityCase>
{
};

TEST_P(IntensityTypes, AnyNumericTypeIsConverted)
{
  const IntensityCase& param = GetParam();
  CloudSpec spec;
  spec.fields = xyzFields();
  spec.fields.push_back({ "intensity", param.datatype, 13 });  // odd offset: unaligned
  spec.point_step = 24;
  spec.width = static_cast<std::uint32_t>(param.values.size());
  std::vector<PointValues> points;
  for (std::size_t i = 0; i < param.values.size(); ++i)
  {
    points.push_back({ 1.0, 2.0, 3.0 + static_cast<double>(i), param.values[i] });
  }
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, points), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(report.warnings.empty()) << joinWarnings(report);
  ASSERT_EQ(out.size(), param.values.size());
  for (std::size_t i = 0; i < param.values.size(); ++i)
  {
    EXPECT_EQ(out[i].intensity, static_cast<float>(param.values[i])) << "datatype " << int(param.datatype);
  }
}

INSTANTIATE_TEST_SUITE_P(PointCloud2Reader, IntensityTypes,
                         ::testing::Values(IntensityCase{ PointField::UINT8, { 0, 17, 255 } },
                                           IntensityCase{ PointField::UINT16, { 0, 300, 65535 } },
                                           IntensityCase{ PointField::FLOAT32, { 0.5, 100.25, 3.5e3 } },
                                           IntensityCase{ PointField::INT8, { -128, -1, 127 } },
                                           IntensityCase{ PointField::INT16, { -32768, 5, 32767 } },
                                           IntensityCase{ PointField::INT32, { -70000, 0, 123456 } },
                                           IntensityCase{ PointField::UINT32, { 0, 4000000, 16777216 } },
                                           IntensityCase{ PointField::FLOAT64, { 0.125, 1e4, -2.5 } }));

TEST(PointCloud2Reader, MissingIntensityWarnsAndZeroes)
{
  CloudSpec spec;
  spec.fields = xyzFields();
  spec.point_step = 16;  // bytes 12..15 hold fill bytes that must not be taken for intensity
  spec.width = 4;
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, simpleXyziPoints(4)), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(hasWarning(report, "intensity")) << joinWarnings(report);
  ASSERT_EQ(out.size(), 4u);
  for (const auto& p : out)
  {
    EXPECT_EQ(p.intensity, 0.0f);
  }
  EXPECT_FALSE(report.has_ring);
  EXPECT_FALSE(report.has_time);
}

TEST(PointCloud2Reader, RingUint8AndUint16AndInt32)
{
  for (const std::uint8_t datatype : { PointField::UINT8, PointField::UINT16, PointField::INT32 })
  {
    CloudSpec spec = xyziSpec(4);
    spec.fields.push_back({ "ring", datatype, 16 });
    spec.point_step = 20;
    const double big_ring = datatype == PointField::UINT8 ? 255.0 : 300.0;
    std::vector<PointValues> points = simpleXyziPoints(4);
    const std::vector<double> rings = { 0.0, 5.0, 63.0, big_ring };
    for (std::size_t i = 0; i < 4; ++i)
    {
      points[i].push_back(rings[i]);
    }
    aloam::Cloud out;
    const ReadReport report = readPointCloud2(makeCloud(spec, points), ReaderOptions(), out);
    ASSERT_TRUE(report.ok) << report.error;
    EXPECT_TRUE(report.has_ring);
    EXPECT_TRUE(report.warnings.empty()) << joinWarnings(report);
    ASSERT_EQ(out.size(), 4u);
    for (std::size_t i = 0; i < 4; ++i)
    {
      EXPECT_EQ(out[i].ring, static_cast<std::uint16_t>(rings[i])) << "datatype " << int(datatype);
    }
  }
}

TEST(PointCloud2Reader, RingOutOfRangeIsClampedWithWarning)
{
  CloudSpec spec = xyziSpec(2);
  spec.fields.push_back({ "ring", PointField::INT32, 16 });
  spec.point_step = 20;
  std::vector<PointValues> points = simpleXyziPoints(2);
  points[0].push_back(-3.0);
  points[1].push_back(70000.0);
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, points), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(hasWarning(report, "clamped")) << joinWarnings(report);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].ring, 0);
  EXPECT_EQ(out[1].ring, 65535);
}

TEST(PointCloud2Reader, FloatRingIsIgnoredWithWarning)
{
  CloudSpec spec = xyziSpec(2);
  spec.fields.push_back({ "ring", PointField::FLOAT32, 16 });
  spec.point_step = 20;
  std::vector<PointValues> points = simpleXyziPoints(2);
  points[0].push_back(3.0);
  points[1].push_back(4.0);
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, points), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_FALSE(report.has_ring);
  EXPECT_TRUE(hasWarning(report, "'ring'")) << joinWarnings(report);
  EXPECT_EQ(out[0].ring, 0);
  EXPECT_EQ(out[1].ring, 0);
}

TEST(PointCloud2Reader, VelodyneTimeRelativeToLastPointIsShiftedToStartAtZero)
{
  CloudSpec spec = xyziSpec(5);
  spec.fields.push_back({ "time", PointField::FLOAT32, 16 });
  spec.point_step = 20;
  const std::vector<float> times = { -0.0999f, -0.075f, -0.05f, -0.02f, 0.0f };
  std::vector<PointValues> points = simpleXyziPoints(5);
  for (std::size_t i = 0; i < 5; ++i)
  {
    points[i].push_back(times[i]);
  }
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, points), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(report.has_time);
  EXPECT_EQ(report.time_field, "time");
  EXPECT_NEAR(report.time_origin, -0.0999, 1e-6);
  ASSERT_EQ(out.size(), 5u);
  EXPECT_EQ(out[0].time, 0.0f);
  for (std::size_t i = 0; i < 5; ++i)
  {
    EXPECT_GE(out[i].time, 0.0f);
    EXPECT_NEAR(out[i].time, static_cast<double>(times[i]) - static_cast<double>(times[0]), 1e-6) << i;
    EXPECT_NEAR(out[i].time + report.time_origin, times[i], 1e-6);
  }
  EXPECT_NEAR(out[4].time - out[3].time, 0.02, 1e-6);
}

TEST(PointCloud2Reader, OusterNanosecondsInRealisticLayout)
{
  // os_cloud_node layout: x y z (pad) intensity t reflectivity ring ambient (pad) range, 48 bytes.
  CloudSpec spec;
  spec.fields = xyzFields();
  spec.fields.push_back({ "intensity", PointField::FLOAT32, 16 });
  spec.fields.push_back({ "t", PointField::UINT32, 20 });
  spec.fields.push_back({ "reflectivity", PointField::UINT16, 24 });
  spec.fields.push_back({ "ring", PointField::UINT16, 26 });
  spec.fields.push_back({ "ambient", PointField::UINT16, 28 });
  spec.fields.push_back({ "range", PointField::UINT32, 32 });
  spec.point_step = 48;
  spec.width = 4;
  const std::vector<double> t_ns = { 50e6, 25e6, 99.9e6, 40e6 };
  std::vector<PointValues> points;
  for (std::size_t i = 0; i < 4; ++i)
  {
    points.push_back({ 1.0 + i, 2.0, 3.0, 100.0, t_ns[i], 7.0, static_cast<double>(i), 9.0, 1234.0 });
  }
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, points), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(report.has_time);
  EXPECT_TRUE(report.has_ring);
  EXPECT_EQ(report.time_field, "t");
  EXPECT_NEAR(report.time_origin, 0.025, 1e-9);
  ASSERT_EQ(out.size(), 4u);
  EXPECT_NEAR(out[0].time, 0.025, 1e-7);
  EXPECT_EQ(out[1].time, 0.0f);
  EXPECT_NEAR(out[2].time, 0.0749, 1e-7);
  EXPECT_NEAR(out[3].time, 0.015, 1e-7);
  EXPECT_EQ(out[2].ring, 2);
  EXPECT_EQ(out[2].intensity, 100.0f);
}

TEST(PointCloud2Reader, AbsoluteFloat64TimestampKeepsSubMicrosecondDifferences)
{
  CloudSpec spec = xyziSpec(4);
  spec.fields.push_back({ "timestamp", PointField::FLOAT64, 16 });
  spec.point_step = 24;
  const double base = 1700000000.0;
  const std::vector<double> offsets = { 0.03, 0.0, 0.0912345, 0.06 };
  std::vector<PointValues> points = simpleXyziPoints(4);
  for (std::size_t i = 0; i < 4; ++i)
  {
    points[i].push_back(base + offsets[i]);
  }
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, points), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(report.has_time);
  EXPECT_EQ(report.time_field, "timestamp");
  EXPECT_NEAR(report.time_origin, base, 1e-6);
  ASSERT_EQ(out.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i)
  {
    EXPECT_NEAR(out[i].time, offsets[i], 1e-6) << i;
  }
}

TEST(PointCloud2Reader, TimePrefersTimeOverTAndTimestamp)
{
  CloudSpec spec = xyziSpec(2);
  spec.fields.push_back({ "timestamp", PointField::FLOAT64, 16 });
  spec.fields.push_back({ "time", PointField::FLOAT32, 24 });
  spec.point_step = 28;
  std::vector<PointValues> points = simpleXyziPoints(2);
  points[0].insert(points[0].end(), { 1.7e9, 0.0 });
  points[1].insert(points[1].end(), { 1.7e9 + 0.05, 0.01 });
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, points), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_EQ(report.time_field, "time");
  EXPECT_NEAR(out[1].time, 0.01, 1e-7);
}

TEST(PointCloud2Reader, TimeSpanBeyondTwoScanPeriodsDisablesTime)
{
  CloudSpec spec = xyziSpec(3);
  spec.fields.push_back({ "time", PointField::FLOAT32, 16 });
  spec.point_step = 20;
  std::vector<PointValues> points = simpleXyziPoints(3);
  points[0].push_back(0.0);
  points[1].push_back(0.1);
  points[2].push_back(0.5);
  const auto msg = makeCloud(spec, points);

  aloam::Cloud out;
  ReadReport report = readPointCloud2(msg, ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_FALSE(report.has_time);
  EXPECT_TRUE(hasWarning(report, "spans")) << joinWarnings(report);
  for (const auto& p : out)
  {
    EXPECT_EQ(p.time, 0.0f);
  }

  ReaderOptions slow;
  slow.scan_period = 0.3;  // 2 * 0.3 > 0.5: accepted
  report = readPointCloud2(msg, slow, out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(report.has_time);
  EXPECT_NEAR(out[2].time, 0.5, 1e-7);
}

TEST(PointCloud2Reader, ConstantTimeDisablesTime)
{
  CloudSpec spec = xyziSpec(3);
  spec.fields.push_back({ "time", PointField::FLOAT32, 16 });
  spec.point_step = 20;
  std::vector<PointValues> points = simpleXyziPoints(3);
  for (auto& p : points)
  {
    p.push_back(-0.05);  // a driver that stamps every point alike
  }
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, points), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_FALSE(report.has_time);
  EXPECT_TRUE(report.time_field.empty());
  EXPECT_TRUE(hasWarning(report, "same value")) << joinWarnings(report);
  for (const auto& p : out)
  {
    EXPECT_EQ(p.time, 0.0f);
  }
}

TEST(PointCloud2Reader, NonFiniteTimeDisablesTime)
{
  CloudSpec spec = xyziSpec(3);
  spec.fields.push_back({ "time", PointField::FLOAT32, 16 });
  spec.point_step = 20;
  std::vector<PointValues> points = simpleXyziPoints(3);
  points[0].push_back(0.0);
  points[1].push_back(kNaN);
  points[2].push_back(0.02);
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, points), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_FALSE(report.has_time);
  EXPECT_TRUE(hasWarning(report, "non-finite")) << joinWarnings(report);
  ASSERT_EQ(out.size(), 3u);
  for (const auto& p : out)
  {
    EXPECT_EQ(p.time, 0.0f);
  }
}

class MissingCoordinate : public ::testing::TestWithParam<std::string>
{
};

TEST_P(MissingCoordinate, IsAnErrorNamingTheField)
{
  CloudSpec spec = xyziSpec(3);
  spec.fields.erase(
      std::remove_if(spec.fields.begin(), spec.fields.end(), [&](const FieldDef& f) { return f.name == GetParam(); }),
      spec.fields.end());
  aloam::Cloud out;
  out.push_back(aloam::Point());  // stale content must be cleared
  const ReadReport report = readPointCloud2(makeCloud(spec, simpleXyziPoints(3)), ReaderOptions(), out);
  EXPECT_FALSE(report.ok);
  EXPECT_NE(report.error.find("'" + GetParam() + "'"), std::string::npos) << report.error;
  EXPECT_NE(report.error.find("missing"), std::string::npos) << report.error;
  EXPECT_EQ(report.points_out, 0u);
  EXPECT_TRUE(out.empty());
}

INSTANTIATE_TEST_SUITE_P(PointCloud2Reader, MissingCoordinate, ::testing::Values("x", "y", "z"));

TEST(PointCloud2Reader, IntegerCoordinatesAreAnError)
{
  CloudSpec spec;
  spec.fields = xyzFields(PointField::INT16);
  spec.point_step = 6;
  spec.width = 2;
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, { { 1, 2, 3 }, { 4, 5, 6 } }), ReaderOptions(), out);
  EXPECT_FALSE(report.ok);
  EXPECT_NE(report.error.find("'x'"), std::string::npos) << report.error;
  EXPECT_NE(report.error.find("FLOAT32"), std::string::npos) << report.error;
}

TEST(PointCloud2Reader, NanInfAndZeroPointsAreDroppedAndCounted)
{
  CloudSpec spec = xyziSpec(9);
  const std::vector<PointValues> points = {
    { 1.0, 2.0, 3.0, 11.0 },   // kept
    { kNaN, 1.0, 1.0, 0.0 },   // dropped
    { 1.0, kInf, 1.0, 0.0 },   // dropped
    { 1.0, 1.0, -kInf, 0.0 },  // dropped
    { 0.0, 0.0, 0.0, 0.0 },    // dropped: driver hole
    { -0.0, 0.0, -0.0, 0.0 },  // dropped: negative zero is zero
    { 0.0, 0.0, 1.0, 12.0 },   // kept: only partly zero
    { 1e300, 1.0, 1.0, 0.0 },  // float32 overflow becomes Inf: dropped
    { -4.0, 0.0, 0.0, 13.0 },  // kept
  };
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, points), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_EQ(report.points_in, 9u);
  EXPECT_EQ(report.points_out, 3u);
  EXPECT_EQ(report.dropped_invalid, 6u);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out[0].intensity, 11.0f);
  EXPECT_EQ(out[1].z, 1.0f);
  EXPECT_EQ(out[1].intensity, 12.0f);
  EXPECT_EQ(out[2].x, -4.0f);
  EXPECT_EQ(out[2].intensity, 13.0f);
  EXPECT_TRUE(out.is_dense);
}

TEST(PointCloud2Reader, AllPointsInvalidIsAnError)
{
  CloudSpec spec = xyziSpec(2);
  aloam::Cloud out;
  const ReadReport report =
      readPointCloud2(makeCloud(spec, { { 0, 0, 0, 1 }, { kNaN, 0, 0, 1 } }), ReaderOptions(), out);
  EXPECT_FALSE(report.ok);
  EXPECT_EQ(report.dropped_invalid, 2u);
  EXPECT_NE(report.error.find("no valid points"), std::string::npos) << report.error;
  EXPECT_TRUE(out.empty());
}

TEST(PointCloud2Reader, OrganizedCloudWithHolesIsFlattenedRowByRow)
{
  constexpr std::uint32_t kWidth = 8;
  constexpr std::uint32_t kHeight = 4;
  CloudSpec spec = xyziSpec(kWidth, kHeight);
  spec.fields.push_back({ "ring", PointField::UINT16, 16 });
  spec.point_step = 18;
  spec.row_padding = 6;
  std::vector<PointValues> points;
  std::vector<PointValues> expected;
  for (std::uint32_t r = 0; r < kHeight; ++r)
  {
    for (std::uint32_t c = 0; c < kWidth; ++c)
    {
      const bool hole = (r + c) % 3 == 0;
      const PointValues p = { hole ? kNaN : 10.0 * r + c + 1, static_cast<double>(r), static_cast<double>(c),
                              static_cast<double>(r * kWidth + c), static_cast<double>(r) };
      points.push_back(p);
      if (!hole)
      {
        expected.push_back(p);
      }
    }
  }
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, points), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(report.warnings.empty()) << joinWarnings(report);
  EXPECT_EQ(report.points_in, 32u);
  EXPECT_EQ(report.dropped_invalid, 32u - expected.size());
  ASSERT_EQ(out.size(), expected.size());
  EXPECT_EQ(out.height, 1u);
  EXPECT_EQ(out.width, expected.size());
  EXPECT_TRUE(out.is_dense);
  for (std::size_t i = 0; i < expected.size(); ++i)
  {
    EXPECT_EQ(out[i].x, static_cast<float>(expected[i][0])) << i;
    EXPECT_EQ(out[i].y, static_cast<float>(expected[i][1])) << i;
    EXPECT_EQ(out[i].z, static_cast<float>(expected[i][2])) << i;
    EXPECT_EQ(out[i].intensity, static_cast<float>(expected[i][3])) << i;
    EXPECT_EQ(out[i].ring, static_cast<std::uint16_t>(expected[i][4])) << i;
  }
}

TEST(PointCloud2Reader, RowPaddingBytesAreSkipped)
{
  CloudSpec spec = xyziSpec(3, 2);
  spec.row_padding = 7;  // filled with kFillByte, which decodes to finite, non-zero floats
  const auto points = simpleXyziPoints(6);
  const auto msg = makeCloud(spec, points);
  ASSERT_EQ(msg.row_step, 3u * 16u + 7u);
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(msg, ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(report.warnings.empty()) << joinWarnings(report);
  ASSERT_EQ(out.size(), 6u);
  for (std::size_t i = 0; i < 6; ++i)
  {
    EXPECT_EQ(out[i].x, static_cast<float>(points[i][0])) << i;
    EXPECT_EQ(out[i].y, static_cast<float>(points[i][1])) << i;
    EXPECT_EQ(out[i].z, static_cast<float>(points[i][2])) << i;
    EXPECT_EQ(out[i].intensity, static_cast<float>(points[i][3])) << i;
  }
}

TEST(PointCloud2Reader, ZeroOrTooSmallRowStepIsRepairedWithWarning)
{
  for (const std::uint32_t bad_row_step : { 0u, 20u })
  {
    CloudSpec spec = xyziSpec(3, 2);
    const auto points = simpleXyziPoints(6);
    auto msg = makeCloud(spec, points);
    msg.row_step = bad_row_step;
    aloam::Cloud out;
    const ReadReport report = readPointCloud2(msg, ReaderOptions(), out);
    ASSERT_TRUE(report.ok) << report.error;
    EXPECT_TRUE(hasWarning(report, "row_step")) << joinWarnings(report);
    ASSERT_EQ(out.size(), 6u);
    EXPECT_EQ(out[5].x, static_cast<float>(points[5][0]));
  }
}

TEST(PointCloud2Reader, ShortDataReadsOnlyCompletePoints)
{
  CloudSpec spec = xyziSpec(10);
  const auto points = simpleXyziPoints(10);
  auto msg = makeCloud(spec, points);
  msg.data.resize(6 * 16 + 7);  // six complete points and a torn seventh
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(msg, ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(hasWarning(report, "complete")) << joinWarnings(report);
  EXPECT_EQ(report.points_in, 10u);
  EXPECT_EQ(report.points_out, 6u);
  ASSERT_EQ(out.size(), 6u);
  EXPECT_EQ(out[5].x, static_cast<float>(points[5][0]));
}

TEST(PointCloud2Reader, ShortOrganizedDataStopsInsideTheTornRow)
{
  CloudSpec spec = xyziSpec(4, 3);
  spec.row_padding = 4;  // row_step 68
  const auto points = simpleXyziPoints(12);
  auto msg = makeCloud(spec, points);
  msg.data.resize(68 + 2 * 16 + 3);  // row 0 complete, two points of row 1
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(msg, ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_EQ(report.points_out, 6u);
  ASSERT_EQ(out.size(), 6u);
  EXPECT_EQ(out[5].x, static_cast<float>(points[5][0]));
}

TEST(PointCloud2Reader, MissingPaddingAfterLastRowIsTolerated)
{
  CloudSpec spec = xyziSpec(4, 2);
  spec.row_padding = 4;
  auto msg = makeCloud(spec, simpleXyziPoints(8));
  msg.data.resize(msg.data.size() - 4);
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(msg, ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_EQ(report.points_out, 8u);
  EXPECT_TRUE(hasWarning(report, "padding")) << joinWarnings(report);
}

TEST(PointCloud2Reader, NoCompletePointIsAnError)
{
  for (const std::size_t size : { std::size_t{ 0 }, std::size_t{ 7 }, std::size_t{ 15 } })
  {
    auto msg = makeCloud(xyziSpec(10), simpleXyziPoints(10));
    msg.data.resize(size);
    aloam::Cloud out;
    const ReadReport report = readPointCloud2(msg, ReaderOptions(), out);
    EXPECT_FALSE(report.ok) << size;
    EXPECT_NE(report.error.find("no complete point"), std::string::npos) << report.error;
    EXPECT_TRUE(out.empty());
  }
}

TEST(PointCloud2Reader, EveryTruncationLengthIsSafe)
{
  CloudSpec spec;
  spec.fields = xyzFields(PointField::FLOAT64);
  spec.fields.push_back({ "intensity", PointField::UINT16, 24 });
  spec.fields.push_back({ "ring", PointField::UINT8, 26 });
  spec.fields.push_back({ "t", PointField::UINT32, 27 });
  spec.point_step = 31;
  spec.width = 5;
  spec.height = 3;
  spec.row_padding = 3;
  std::vector<PointValues> points;
  for (int i = 0; i < 15; ++i)
  {
    points.push_back({ 1.0 + i, 2.0, 3.0, 40.0, static_cast<double>(i % 16), 1000.0 * i });
  }
  const auto full = makeCloud(spec, points);
  for (std::size_t size = 0; size <= full.data.size(); ++size)
  {
    auto msg = full;
    msg.data.resize(size);
    msg.data.shrink_to_fit();  // let a sanitizer see reads past the end
    const std::size_t full_rows = size / msg.row_step;
    const std::size_t expected =
        std::min<std::size_t>(15, full_rows * 5 + std::min<std::size_t>(5, (size - full_rows * msg.row_step) / 31));
    aloam::Cloud out;
    const ReadReport report = readPointCloud2(msg, ReaderOptions(), out);
    EXPECT_EQ(report.points_out, expected) << size;
    EXPECT_EQ(report.ok, expected > 0) << size;
    for (std::size_t i = 0; i < out.size(); ++i)
    {
      EXPECT_EQ(out[i].x, static_cast<float>(1.0 + i));
    }
  }
}

TEST(PointCloud2Reader, PointStepSmallerThanCoordinatesIsAnError)
{
  CloudSpec spec = xyziSpec(2);
  spec.fields.pop_back();
  spec.point_step = 8;  // z at offset 8 does not fit
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, simpleXyziPoints(2)), ReaderOptions(), out);
  EXPECT_FALSE(report.ok);
  EXPECT_NE(report.error.find("'z'"), std::string::npos) << report.error;
  EXPECT_NE(report.error.find("point_step"), std::string::npos) << report.error;

  spec.point_step = 0;
  const ReadReport zero_step = readPointCloud2(makeCloud(spec, simpleXyziPoints(2)), ReaderOptions(), out);
  EXPECT_FALSE(zero_step.ok);
  EXPECT_NE(zero_step.error.find("point_step"), std::string::npos) << zero_step.error;
}

TEST(PointCloud2Reader, OptionalFieldsBeyondPointStepAreIgnored)
{
  CloudSpec spec;
  spec.fields = xyzFields();
  spec.fields.push_back({ "intensity", PointField::FLOAT32, 14 });  // 14 + 4 > 16
  spec.fields.push_back({ "ring", PointField::UINT16, 15 });        // 15 + 2 > 16
  spec.fields.push_back({ "time", PointField::FLOAT32, 200 });
  spec.point_step = 16;
  spec.width = 2;
  aloam::Cloud out;
  const ReadReport report =
      readPointCloud2(makeCloud(spec, { { 1, 2, 3, 4, 5, 6 }, { 2, 3, 4, 5, 6, 7 } }), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_FALSE(report.has_ring);
  EXPECT_FALSE(report.has_time);
  EXPECT_TRUE(hasWarning(report, "'intensity'")) << joinWarnings(report);
  EXPECT_TRUE(hasWarning(report, "'ring'")) << joinWarnings(report);
  EXPECT_TRUE(hasWarning(report, "'time'")) << joinWarnings(report);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[1].x, 2.0f);
  EXPECT_EQ(out[1].intensity, 0.0f);
  EXPECT_EQ(out[1].ring, 0);
  EXPECT_EQ(out[1].time, 0.0f);
}

TEST(PointCloud2Reader, UnknownDatatypes)
{
  for (const std::uint8_t bad : { std::uint8_t{ 0 }, std::uint8_t{ 9 }, kUnknownDatatype })
  {
    CloudSpec spec = xyziSpec(2);
    spec.fields[0].datatype = bad;
    aloam::Cloud out;
    const ReadReport report = readPointCloud2(makeCloud(spec, simpleXyziPoints(2)), ReaderOptions(), out);
    EXPECT_FALSE(report.ok);
    EXPECT_NE(report.error.find("unknown datatype"), std::string::npos) << report.error;
    EXPECT_NE(report.error.find("'x'"), std::string::npos) << report.error;
  }

  CloudSpec spec = xyziSpec(2);
  spec.fields[3].datatype = kUnknownDatatype;
  spec.fields.push_back({ "t", kUnknownDatatype, 12 });
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, simpleXyziPoints(2)), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(hasWarning(report, "'intensity' has unknown datatype")) << joinWarnings(report);
  EXPECT_TRUE(hasWarning(report, "'t' has unknown datatype")) << joinWarnings(report);
  EXPECT_FALSE(report.has_time);
  EXPECT_EQ(out[0].intensity, 0.0f);
}

TEST(PointCloud2Reader, FieldCountOtherThanOneUsesFirstElement)
{
  CloudSpec spec = xyziSpec(2);
  spec.fields[3].count = 3;  // intensity[3] at 12..23
  spec.point_step = 24;
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(makeCloud(spec, simpleXyziPoints(2)), ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(hasWarning(report, "count 3")) << joinWarnings(report);
  EXPECT_EQ(out[1].intensity, 11.0f);
}

TEST(PointCloud2Reader, BigEndianDecodesLikeLittleEndian)
{
  for (const std::uint8_t intensity_type :
       { PointField::INT8, PointField::UINT8, PointField::INT16, PointField::UINT16, PointField::INT32,
         PointField::UINT32, PointField::FLOAT32, PointField::FLOAT64 })
  {
    CloudSpec spec;
    spec.fields = { { "x", PointField::FLOAT32, 0 },    { "y", PointField::FLOAT64, 4 },
                    { "z", PointField::FLOAT32, 12 },   { "intensity", intensity_type, 16 },
                    { "ring", PointField::UINT16, 24 }, { "t", PointField::UINT32, 26 } };
    spec.point_step = 30;
    spec.width = 6;
    spec.height = 2;
    spec.row_padding = 5;
    std::vector<PointValues> points;
    for (int i = 0; i < 12; ++i)
    {
      points.push_back({ 0.37 * i - 1.1, -2.25 * i + 0.1, 1e-3 * i + 0.5, static_cast<double>(100 + i),
                         static_cast<double>(i * 3), 1234567.0 * i });
    }
    const auto little = makeCloud(spec, points);
    spec.big_endian = true;
    const auto big = makeCloud(spec, points);
    ASSERT_NE(little.data, big.data);

    aloam::Cloud out_little;
    aloam::Cloud out_big;
    const ReadReport report_little = readPointCloud2(little, ReaderOptions(), out_little);
    const ReadReport report_big = readPointCloud2(big, ReaderOptions(), out_big);
    ASSERT_TRUE(report_little.ok) << report_little.error;
    ASSERT_TRUE(report_big.ok) << report_big.error;
    EXPECT_TRUE(report_big.has_time);
    EXPECT_TRUE(report_big.has_ring);
    ASSERT_EQ(out_big.size(), 12u);
    ASSERT_EQ(out_little.size(), 12u);
    for (std::size_t i = 0; i < 12; ++i)
    {
      EXPECT_EQ(out_big[i].x, out_little[i].x);
      EXPECT_EQ(out_big[i].y, out_little[i].y);
      EXPECT_EQ(out_big[i].z, out_little[i].z);
      EXPECT_EQ(out_big[i].intensity, out_little[i].intensity);
      EXPECT_EQ(out_big[i].ring, out_little[i].ring);
      EXPECT_EQ(out_big[i].time, out_little[i].time);
      // And both equal the source values.
      EXPECT_EQ(out_big[i].y, static_cast<float>(points[i][1]));
      EXPECT_EQ(out_big[i].intensity, static_cast<float>(points[i][3]));
      EXPECT_EQ(out_big[i].ring, i * 3);
      EXPECT_NEAR(out_big[i].time, 1234567e-9 * i, 1e-9);
    }
  }
}

TEST(PointCloud2Reader, MaxPointsCapsTheOutput)
{
  auto points = simpleXyziPoints(5000);
  points[0][0] = kNaN;  // the cap counts kept points, not read ones
  const auto msg = makeCloud(xyziSpec(5000), points);
  ReaderOptions options;
  options.max_points = 1000;
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(msg, options, out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(hasWarning(report, "max_points")) << joinWarnings(report);
  EXPECT_EQ(report.points_out, 1000u);
  EXPECT_EQ(report.dropped_invalid, 1u);
  ASSERT_EQ(out.size(), 1000u);
  EXPECT_EQ(out.width, 1000u);
  EXPECT_EQ(out.front().x, static_cast<float>(points[1][0]));
  EXPECT_EQ(out.back().x, static_cast<float>(points[1000][0]));

  options.max_points = 0;  // no cap
  const ReadReport uncapped = readPointCloud2(msg, options, out);
  EXPECT_EQ(uncapped.points_out, 4999u);
  EXPECT_FALSE(hasWarning(uncapped, "max_points"));
}

TEST(PointCloud2Reader, EnormousCloudIsCappedAtDefaultMaxPoints)
{
  constexpr std::uint32_t kPoints = 2'000'010;
  CloudSpec spec;
  spec.fields = xyzFields();
  spec.point_step = 12;
  spec.width = kPoints;
  auto msg = makeCloud(spec, {});  // every point is fill bytes: finite and non-zero
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(msg, ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_EQ(report.points_in, kPoints);
  EXPECT_EQ(report.points_out, ReaderOptions().max_points);
  EXPECT_EQ(out.size(), ReaderOptions().max_points);
  EXPECT_TRUE(hasWarning(report, "max_points")) << joinWarnings(report);
}

TEST(PointCloud2Reader, EmptyCloudIsAnError)
{
  for (const auto& [width, height] : { std::pair<std::uint32_t, std::uint32_t>{ 0, 1 }, { 5, 0 }, { 0, 0 } })
  {
    CloudSpec spec = xyziSpec(width, height);
    aloam::Cloud out;
    const ReadReport report = readPointCloud2(makeCloud(spec, {}), ReaderOptions(), out);
    EXPECT_FALSE(report.ok);
    EXPECT_NE(report.error.find("empty cloud"), std::string::npos) << report.error;
    EXPECT_EQ(report.points_in, 0u);
    EXPECT_TRUE(out.empty());
  }
}

TEST(PointCloud2Reader, EmptyFrameIdIsOnlyAWarning)
{
  auto msg = makeCloud(xyziSpec(2), simpleXyziPoints(2));
  msg.header.frame_id.clear();
  aloam::Cloud out;
  const ReadReport report = readPointCloud2(msg, ReaderOptions(), out);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_TRUE(hasWarning(report, "frame_id")) << joinWarnings(report);
  EXPECT_EQ(out.size(), 2u);
}

// Large clouds are decoded in stretches over the reading stage's threads: the cloud and the report must
// not depend on them. An organized cloud with row padding, ring and time fields, holes everywhere and a
// first stretch that holds no valid point (the time reference lies in a later one), little- and
// big-endian, against the decode on the caller; and a cloud read into one that held more points before.
TEST(PointCloud2Reader, ThreadsDoNotChangeTheCloud)
{
  constexpr std::uint32_t kWidth = 1200;
  constexpr std::uint32_t kHeight = 64;
  for (const bool big_endian : { false, true })
  {
    CloudSpec spec = xyziSpec(kWidth, kHeight);
    spec.fields.push_back({ "ring", PointField::UINT16, 16 });
    spec.fields.push_back({ "time", PointField::FLOAT64, 18 });
    spec.point_step = 26;
    spec.row_padding = 5;
    spec.big_endian = big_endian;
    std::vector<PointValues> points;
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> coordinate(-40.0, 40.0);
    for (std::uint32_t r = 0; r < kHeight; ++r)
    {
      for (std::uint32_t c = 0; c < kWidth; ++c)
      {
        const std::size_t i = points.size();
        const bool hole = i < 30000 || i % 7 == 3 || (r == 40 && c > 600);
        points.push_back({ hole ? kNaN : coordinate(rng), coordinate(rng), coordinate(rng),
                           static_cast<double>(i % 256), static_cast<double>(r), 1.7e9 + 1e-6 * c + 2e-7 * r });
      }
    }
    const auto msg = makeCloud(spec, points);
    aloam::Cloud serial;
    const ReadReport expected = readPointCloud2(msg, ReaderOptions(), serial);
    ASSERT_TRUE(expected.ok) << expected.error;
    ASSERT_TRUE(expected.has_time);
    ASSERT_GT(expected.dropped_invalid, 30000u);
    for (const int threads : { 2, 3, 4 })
    {
      aloam::Executor executor(threads);
      ReaderOptions options;
      options.executor = &executor;
      aloam::Cloud parallel = serial;
      parallel.points.resize(serial.size() + 1000);  // stale points beyond what the read keeps
      const ReadReport report = readPointCloud2(msg, options, parallel);
      ASSERT_TRUE(report.ok) << report.error;
      EXPECT_EQ(report.points_out, expected.points_out) << threads;
      EXPECT_EQ(report.dropped_invalid, expected.dropped_invalid) << threads;
      EXPECT_EQ(report.time_origin, expected.time_origin) << threads;
      EXPECT_EQ(joinWarnings(report), joinWarnings(expected)) << threads;
      ASSERT_EQ(parallel.size(), serial.size()) << threads;
      EXPECT_EQ(parallel.width, serial.width);
      for (std::size_t i = 0; i < serial.size(); ++i)
      {
        const aloam::Point &a = serial[i], &b = parallel[i];
        ASSERT_TRUE(a.x == b.x && a.y == b.y && a.z == b.z && a.intensity == b.intensity && a.ring == b.ring &&
                    a.time == b.time)
            << "point " << i << ", " << threads << " threads";
      }
    }
  }
  // An unusable message leaves nothing of the cloud read before.
  aloam::Cloud reused = aloam::Cloud();
  reused.points.resize(10);
  CloudSpec empty_spec = xyziSpec(0);
  EXPECT_FALSE(readPointCloud2(makeCloud(empty_spec, {}), ReaderOptions(), reused).ok);
  EXPECT_TRUE(reused.empty());
}

TEST(PointCloud2Reader, RandomMalformedMessagesNeverCrash)
{
  const std::vector<std::string> names = { "x", "y", "z", "intensity", "ring", "time", "t", "timestamp" };
  std::mt19937 rng(12345);
  auto uniform = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  for (int iteration = 0; iteration < 3000; ++iteration)
  {
    sensor_msgs::PointCloud2 msg;
    msg.header.frame_id = "f";
    msg.width = static_cast<std::uint32_t>(uniform(0, 20));
    msg.height = static_cast<std::uint32_t>(uniform(0, 4));
    msg.point_step = static_cast<std::uint32_t>(uniform(0, 40));
    msg.row_step = uniform(0, 3) == 0 ? static_cast<std::uint32_t>(uniform(0, 1000))
                                      : msg.width * msg.point_step + static_cast<std::uint32_t>(uniform(0, 5));
    msg.is_bigendian = uniform(0, 1) == 1;
    for (const std::string& name : names)
    {
      if (uniform(0, 5) == 0 && name != "x")
      {
        continue;
      }
      PointField field;
      field.name = name;
      field.datatype = static_cast<std::uint8_t>(uniform(0, 3) == 0 ? uniform(0, 10) : uniform(7, 8));
      field.offset = static_cast<std::uint32_t>(uniform(0, 40));
      field.count = static_cast<std::uint32_t>(uniform(0, 2));
      msg.fields.push_back(field);
    }
    const std::size_t declared = static_cast<std::size_t>(msg.row_step) * msg.height;
    msg.data.resize(uniform(0, 2) == 0 ? static_cast<std::size_t>(uniform(0, 900)) : declared);
    for (auto& byte : msg.data)
    {
      byte = static_cast<std::uint8_t>(uniform(0, 255));
    }
    msg.data.shrink_to_fit();

    ReaderOptions options;
    options.max_points = static_cast<std::size_t>(uniform(0, 50));
    aloam::Cloud out;
    const ReadReport report = readPointCloud2(msg, options, out);
    EXPECT_LE(report.points_out + report.dropped_invalid, report.points_in);
    EXPECT_EQ(report.points_out, out.size());
    EXPECT_EQ(report.ok, report.error.empty());
    if (report.ok)
    {
      EXPECT_GT(out.size(), 0u);
    }
    if (options.max_points > 0)
    {
      EXPECT_LE(out.size(), options.max_points);
    }
    for (const auto& p : out)
    {
      ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
      ASSERT_FALSE(p.x == 0.0f && p.y == 0.0f && p.z == 0.0f);
      if (report.has_time)
      {
        ASSERT_GE(p.time, 0.0f);
        ASSERT_LE(p.time, 2.0 * options.scan_period + 1e-6);
      }
      else
      {
        ASSERT_EQ(p.time, 0.0f);
      }
    }
  }
}

}  // namespace
