// libFuzzer harness for the stage messages as they arrive from another process: bytes are deserialized
// as aloam_nodelet/FeatureClouds or aloam_nodelet/OdometryFrame into the in-process types, checked
// with validate() as the nodelets do, and what passes goes to the core stage the nodelet would hand it
// to (LaserOdometry, LaserMapping). Nothing may crash, read out of bounds (AddressSanitizer) or hit
// undefined behaviour (UBSan); a refusal must say why.
//
// The first byte picks the message and the mode: raw bytes (mostly refused while deserializing), or a
// message built from the bytes (clouds whose points, rings and times come from the input, sometimes
// NaN/Inf; poses with arbitrary quaternions; absurd widths), serialized and then cut or flipped at a
// position the input gives, so that well-formed and nearly well-formed messages reach the stages.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <new>
#include <string>
#include <vector>

#include <ros/serialization.h>

#include "byte_source.h"
#include "aloam_nodelet/core/laser_mapping.h"
#include "aloam_nodelet/core/laser_odometry.h"
#include "aloam_nodelet/ros/stage_messages.h"

namespace
{
using aloam_fuzz::ByteSource;
using aloam_fuzz::require;

// A cloud of up to 63 points, rings non-decreasing (as registration writes them) unless the input says.
aloam::Cloud makeCloud(ByteSource& in)
{
  aloam::Cloud cloud;
  const int n = in.byte() % 64;
  const bool shuffled_rings = (in.byte() & 7) == 0;
  int ring = 0;
  for (int i = 0; i < n && in.left() > 0; ++i)
  {
    aloam::Point p;
    p.x = in.coordinate();
    p.y = in.coordinate();
    p.z = in.coordinate();
    p.intensity = static_cast<float>(in.byte());
    p.time = (in.byte() & 31) == 0 ? in.f32() : static_cast<float>(in.byte()) / 2550.0f;
    ring = shuffled_rings ? in.byte() : ring + (in.byte() & 1);
    p.ring = static_cast<std::uint16_t>(ring);
    cloud.push_back(p);
  }
  return cloud;
}

aloam::Pose makePose(ByteSource& in)
{
  aloam::Pose pose;
  pose.q = Eigen::Quaterniond(in.i16(), in.i16(), in.i16(), in.i16());
  if ((in.byte() & 3) != 0)
  {
    pose.q.normalize();  // usually a rotation; otherwise whatever the bytes give (also zero)
  }
  pose.t = Eigen::Vector3d(in.coordinate(), in.coordinate(), in.coordinate());
  return pose;
}

template <typename Wire>
std::vector<std::uint8_t> serialize(const Wire& wire)
{
  std::vector<std::uint8_t> buffer(ros::serialization::serializationLength(wire));
  ros::serialization::OStream out(buffer.data(), static_cast<std::uint32_t>(buffer.size()));
  ros::serialization::serialize(out, wire);
  return buffer;
}

// Cuts the buffer short or flips a byte of it, where the input says.
void corrupt(ByteSource& in, std::vector<std::uint8_t>& bytes)
{
  const std::uint8_t how = in.byte() % 4;
  const std::size_t at = bytes.empty() ? 0 : (static_cast<std::size_t>(in.i16() & 0x7fff) * 37) % bytes.size();
  if (how == 1)
  {
    bytes.resize(at);
  }
  else if (how == 2 && !bytes.empty())
  {
    bytes[at] ^= static_cast<std::uint8_t>(1u << (in.byte() % 8));
  }
}

std::vector<std::uint8_t> builtFeatureClouds(ByteSource& in)
{
  auto f = std::make_shared<aloam::FeatureSet>();
  f->scan_period = (in.byte() & 15) == 0 ? static_cast<double>(in.f32()) : 0.1;
  f->has_time = (in.byte() & 1) != 0;
  f->sharp = makeCloud(in);
  f->less_sharp = makeCloud(in);
  f->flat = makeCloud(in);
  f->less_flat = makeCloud(in);
  f->full = makeCloud(in);
  aloam::ros_io::StampedFeatureSet msg;
  msg.header.stamp = ros::Time(in.byte(), 0);
  msg.features = f;
  aloam_nodelet::FeatureClouds wire = aloam::ros_io::toWire(msg);
  if ((in.byte() & 7) == 0)
  {
    wire.less_flat.width = static_cast<std::uint32_t>(in.i16()) << 12;  // absurd count
  }
  std::vector<std::uint8_t> bytes = serialize(wire);
  corrupt(in, bytes);
  return bytes;
}

std::vector<std::uint8_t> builtOdometryFrame(ByteSource& in)
{
  aloam::ros_io::StampedOdometryFrame msg;
  msg.header.stamp = ros::Time(in.byte(), 0);
  msg.frame.pose = makePose(in);
  msg.frame.motion = makePose(in);
  msg.frame.status = static_cast<aloam::OdometryStatus>(in.byte() % 4);
  msg.frame.distorted = (in.byte() & 1) != 0;
  msg.frame.corners = std::make_shared<aloam::Cloud>(makeCloud(in));
  msg.frame.surfs = std::make_shared<aloam::Cloud>(makeCloud(in));
  aloam_nodelet::OdometryFrame wire = aloam::ros_io::toWire(msg);
  wire.status = (in.byte() & 15) == 0 ? in.byte() : wire.status;
  std::vector<std::uint8_t> bytes = serialize(wire);
  corrupt(in, bytes);
  return bytes;
}

// Deserializes as roscpp would (a short or inconsistent buffer throws there, and roscpp drops the
// message); false when that happened. roscpp sizes a vector from its length prefix before it reads the
// elements, so a corrupt prefix asks for up to 200 GB; see operator new below.
template <typename M>
bool deserialize(std::vector<std::uint8_t>& bytes, M& msg)
{
  std::uint8_t none = 0;  // roscpp never hands over a null buffer (advancing one is undefined there)
  try
  {
    ros::serialization::IStream stream(bytes.empty() ? &none : bytes.data(), static_cast<std::uint32_t>(bytes.size()));
    ros::serialization::deserialize(stream, msg);
    return true;
  }
  catch (const std::exception&)
  {
    return false;
  }
}

void feedOdometry(std::vector<std::uint8_t>& bytes)
{
  auto msg = std::make_shared<aloam::ros_io::StampedFeatureSet>();
  if (!deserialize(bytes, *msg))
  {
    return;
  }
  const std::string error = aloam::ros_io::validate(*msg);
  if (!error.empty() || !msg->features)
  {
    return;
  }
  aloam::LaserOdometryConfig config;
  config.threads = 1;
  config.deskew = msg->features->has_time;
  aloam::LaserOdometry odometry(config);
  // The first sweep initializes, the second is matched against it (the same sweep, as after a stop).
  for (int i = 0; i < 2; ++i)
  {
    const aloam::OdometryFrame frame = odometry.process(msg->features);
    require(frame.pose.isFinite());
  }
}

void feedMapping(std::vector<std::uint8_t>& bytes)
{
  aloam::ros_io::StampedOdometryFrame msg;
  if (!deserialize(bytes, msg))
  {
    return;
  }
  if (!aloam::ros_io::validate(msg).empty())
  {
    return;
  }
  aloam::LaserMappingConfig config;
  config.threads = 1;
  aloam::LaserMapping mapping(config);
  for (int i = 0; i < 2; ++i)
  {
    const aloam::MappingResult result = mapping.process(msg.frame);
    require(result.pose.isFinite());
  }
}

// A process asked for gigabytes it cannot have gets std::bad_alloc, and roscpp's deserializer catches it
// and drops the message. AddressSanitizer's operator new aborts instead, so this one refuses big requests
// with the exception (256 MB: nothing these inputs make may need that much). Our own code gets the same
// exception, which nothing catches there: a big request from the stages still fails the fuzzer.
constexpr std::size_t kMaxRequest = std::size_t{ 256 } << 20;

void* allocateOrNull(std::size_t size)
{
  return size <= kMaxRequest ? std::malloc(size == 0 ? 1 : size) : nullptr;
}

void* allocate(std::size_t size)
{
  void* p = allocateOrNull(size);
  if (p == nullptr)
  {
    throw std::bad_alloc();
  }
  return p;
}
}  // namespace

void* operator new(std::size_t size)
{
  return allocate(size);
}
void* operator new[](std::size_t size)
{
  return allocate(size);
}
void* operator new(std::size_t size, const std::nothrow_t&) noexcept
{
  return allocateOrNull(size);
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept
{
  return allocateOrNull(size);
}
void operator delete(void* p) noexcept
{
  std::free(p);
}
void operator delete[](void* p) noexcept
{
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept
{
  std::free(p);
}
void operator delete[](void* p, std::size_t) noexcept
{
  std::free(p);
}
void operator delete(void* p, const std::nothrow_t&) noexcept
{
  std::free(p);
}
void operator delete[](void* p, const std::nothrow_t&) noexcept
{
  std::free(p);
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
  ByteSource in(data, size);
  const std::uint8_t mode = in.byte();
  const bool odometry_frame = (mode & 1) != 0;
  std::vector<std::uint8_t> bytes;
  if ((mode & 2) == 0)
  {
    bytes.assign(data + (size > 0 ? 1 : 0), data + size);
  }
  else
  {
    bytes = odometry_frame ? builtOdometryFrame(in) : builtFeatureClouds(in);
  }
  if (odometry_frame)
  {
    feedMapping(bytes);
  }
  else
  {
    feedOdometry(bytes);
  }
  return 0;
}
