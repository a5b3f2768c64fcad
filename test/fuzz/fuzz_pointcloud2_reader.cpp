// libFuzzer harness for the PointCloud2 reader: the fuzzer's bytes describe a message layout (size,
// steps, endianness, fields with names, types, offsets and counts) followed by its data. The reader must
// never crash, read out of bounds (AddressSanitizer) or hit undefined behaviour (UBSan), and what it
// returns must hold together.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>

#include "byte_source.h"
#include "aloam_nodelet/ros/pointcloud2_reader.h"

namespace
{
// Field names the reader looks for, plus one it must ignore.
const char* const kFieldNames[] = { "x", "y", "z", "intensity", "ring", "time", "t", "timestamp", "other" };
constexpr std::size_t kFieldNameCount = sizeof(kFieldNames) / sizeof(kFieldNames[0]);
constexpr std::size_t kMaxFields = 8;
constexpr std::uint32_t kMaxDimension = 4096;  // keeps width * height * point_step small enough to run fast

using aloam_fuzz::ByteSource;
using aloam_fuzz::require;
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
  ByteSource in(data, size);
  sensor_msgs::PointCloud2 msg;
  msg.width = in.u16() % kMaxDimension;
  msg.height = in.byte() % 8;
  msg.point_step = in.byte();
  msg.row_step = in.u16();
  msg.is_bigendian = (in.byte() & 1) != 0;
  msg.is_dense = (in.byte() & 1) != 0;
  const std::size_t fields = in.byte() % (kMaxFields + 1);
  for (std::size_t i = 0; i < fields; ++i)
  {
    sensor_msgs::PointField field;
    field.name = kFieldNames[in.byte() % kFieldNameCount];
    field.offset = in.byte();
    field.datatype = in.byte() % 10;  // 0 and 9 are not valid datatypes
    field.count = in.byte() % 3;
    msg.fields.push_back(field);
  }
  msg.data.assign(in.rest(), in.rest() + in.left());

  aloam::ros_io::ReaderOptions options;
  options.max_points = 1 + (size % 5000);
  aloam::Cloud out;
  const aloam::ros_io::ReadReport report = aloam::ros_io::readPointCloud2(msg, options, out);

  require(report.ok || !report.error.empty());  // a refusal always says why
  require(out.size() == report.points_out);
  require(out.size() <= options.max_points);
  require(report.points_out + report.dropped_invalid <= static_cast<std::size_t>(msg.width) * msg.height);
  for (const aloam::Point& p : out.points)
  {
    require(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
    require(!report.has_time || (std::isfinite(p.time) && p.time >= 0.0f));
  }
  return 0;
}
