#include "aloam_nodelet/core/graph_file.h"

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>

namespace aloam
{
namespace
{
// Layout (little-endian; f64/f32 IEEE 754): magic, u32 version, the settings, u64 keyframe and edge counts,
// the keyframes, the edges, and a CRC-32 of every byte before it.
constexpr char kMagic[8] = { 'A', 'L', 'O', 'A', 'M', 'G', 'R', 'F' };
constexpr std::uint32_t kMaxSensorName = 256;
constexpr std::uint32_t kMaxDescriptorRings = 1024;
constexpr std::uint32_t kMaxDescriptorSectors = 4096;
constexpr int kMaxSession = 1 << 20;
// The smallest record of each kind (no clouds, no descriptor): a count beyond the bytes left is corrupt.
constexpr std::uint64_t kMinKeyframeBytes = 8 + 4 + 56 + 8 + 1 + 1 + 8;
constexpr std::uint64_t kMinEdgeBytes = 8 + 8 + 56 + 36 * 8 + 1 + 1;
constexpr std::uint64_t kPointBytes = 16;  // x y z intensity, f32 each

class Crc32
{
public:
  Crc32()
  {
    for (std::uint32_t i = 0; i < 256; ++i)
    {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k)
      {
        c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      }
      table_[i] = c;
    }
  }
  void update(const unsigned char* data, std::size_t n)
  {
    for (std::size_t i = 0; i < n; ++i)
    {
      crc_ = table_[(crc_ ^ data[i]) & 0xFFu] ^ (crc_ >> 8);
    }
  }
  std::uint32_t value() const { return crc_ ^ 0xFFFFFFFFu; }

private:
  std::array<std::uint32_t, 256> table_{};
  std::uint32_t crc_ = 0xFFFFFFFFu;
};

void putBytes(unsigned char* p, std::uint64_t v, int n)
{
  for (int i = 0; i < n; ++i)
  {
    p[i] = static_cast<unsigned char>((v >> (8 * i)) & 0xFFu);
  }
}

std::uint64_t getBytes(const unsigned char* p, int n)
{
  std::uint64_t v = 0;
  for (int i = 0; i < n; ++i)
  {
    v |= static_cast<std::uint64_t>(p[i]) << (8 * i);
  }
  return v;
}

// The bits of a value as another type of the same size (IEEE 754 floats to and from their integers).
template <typename To, typename From>
To bitCast(From from)
{
  static_assert(sizeof(To) == sizeof(From), "bitCast needs types of one size");
  To to;
  std::memcpy(&to, &from, sizeof(to));
  return to;
}

/// Little-endian encoding into a buffer written out in large blocks, with the running checksum.
class Writer
{
public:
  Writer(std::ofstream& out, const std::string& path) : out_(out), path_(path) {}

  void raw(const void* data, std::size_t n)
  {
    const auto* p = static_cast<const unsigned char*>(data);
    buffer_.insert(buffer_.end(), p, p + n);
    if (buffer_.size() >= (std::size_t(1) << 20))
    {
      flush();
    }
  }
  void u8(std::uint8_t v) { raw(&v, 1); }
  void u32(std::uint32_t v) { number(v, 4); }
  void u64(std::uint64_t v) { number(v, 8); }
  void i32(std::int32_t v) { number(static_cast<std::uint32_t>(v), 4); }
  void f32(float v) { number(bitCast<std::uint32_t>(v), 4); }
  void f64(double v) { number(bitCast<std::uint64_t>(v), 8); }
  void pose(const Pose& p)
  {
    for (int i = 0; i < 3; ++i)
    {
      f64(p.t[i]);
    }
    f64(p.q.x());
    f64(p.q.y());
    f64(p.q.z());
    f64(p.q.w());
  }
  /// Writes what is buffered and then the checksum of everything written.
  void finish()
  {
    flush();
    unsigned char b[4];
    putBytes(b, crc_.value(), 4);
    out_.write(reinterpret_cast<const char*>(b), 4);
  }

private:
  void number(std::uint64_t v, int n)
  {
    unsigned char b[8];
    putBytes(b, v, n);
    raw(b, static_cast<std::size_t>(n));
  }
  void flush()
  {
    crc_.update(buffer_.data(), buffer_.size());
    out_.write(reinterpret_cast<const char*>(buffer_.data()), static_cast<std::streamsize>(buffer_.size()));
    if (!out_)
    {
      throw GraphFileError("cannot write graph " + path_ + ": " + std::strerror(errno));
    }
    buffer_.clear();
  }

  std::ofstream& out_;
  const std::string& path_;
  std::vector<unsigned char> buffer_;
  Crc32 crc_;
};

/// Little-endian decoding that never reads past the file's end, with the running checksum.
class Reader
{
public:
  Reader(std::ifstream& in, std::uint64_t size, const std::string& path) : in_(in), left_(size), path_(path) {}

  [[noreturn]] void fail(const std::string& why) const
  {
    throw GraphFileError("graph " + path_ + ": " + why + " (at byte " + std::to_string(offset_) + ")");
  }
  std::uint64_t left() const { return left_; }

  void raw(void* out, std::size_t n)
  {
    if (n > left_)
    {
      fail("truncated: " + std::to_string(n) + " more bytes needed, " + std::to_string(left_) + " left");
    }
    in_.read(static_cast<char*>(out), static_cast<std::streamsize>(n));
    if (!in_)
    {
      fail(std::string("read error: ") + std::strerror(errno));
    }
    crc_.update(static_cast<const unsigned char*>(out), n);
    left_ -= n;
    offset_ += n;
  }
  std::uint8_t u8()
  {
    std::uint8_t v;
    raw(&v, 1);
    return v;
  }
  std::uint32_t u32() { return static_cast<std::uint32_t>(number(4)); }
  std::uint64_t u64() { return number(8); }
  std::int32_t i32() { return static_cast<std::int32_t>(static_cast<std::uint32_t>(number(4))); }
  double f64() { return bitCast<double>(number(8)); }
  bool flag(const char* what)
  {
    const std::uint8_t v = u8();
    if (v > 1)
    {
      fail(std::string("corrupt: ") + what + " flag is " + std::to_string(v));
    }
    return v == 1;
  }
  /// A pose with finite values and a unit quaternion (as written).
  Pose pose(const std::string& what)
  {
    Pose p;
    for (int i = 0; i < 3; ++i)
    {
      p.t[i] = f64();
    }
    const double x = f64(), y = f64(), z = f64(), w = f64();
    p.q = Eigen::Quaterniond(w, x, y, z);
    if (!p.isFinite() || std::fabs(p.q.norm() - 1.0) > 1e-6)
    {
      fail("corrupt: " + what + " is not a finite rigid transform");
    }
    return p;
  }
  /// A count of records of at least `min_bytes` each: no more than the bytes left can hold.
  std::uint64_t count(std::uint64_t n, std::uint64_t min_bytes, const std::string& what) const
  {
    if (min_bytes > 0 && n > left_ / min_bytes)
    {
      fail("truncated or corrupt: " + std::to_string(n) + " " + what + " cannot fit in the " + std::to_string(left_) +
           " bytes left");
    }
    return n;
  }
  /// Checks the stored checksum against the bytes read, and that nothing follows it.
  void finish()
  {
    const std::uint32_t computed = crc_.value();
    unsigned char b[4];
    if (left_ < 4)
    {
      fail("truncated: no checksum at the end");
    }
    in_.read(reinterpret_cast<char*>(b), 4);
    left_ -= 4;
    offset_ += 4;
    if (!in_ || static_cast<std::uint32_t>(getBytes(b, 4)) != computed)
    {
      fail("corrupt: the checksum does not match the contents");
    }
    if (left_ != 0)
    {
      fail("corrupt: " + std::to_string(left_) + " bytes after the end of the graph");
    }
  }

private:
  std::uint64_t number(int n)
  {
    unsigned char b[8];
    raw(b, static_cast<std::size_t>(n));
    return getBytes(b, n);
  }

  std::ifstream& in_;
  std::uint64_t left_;
  std::uint64_t offset_ = 0;
  const std::string& path_;
  Crc32 crc_;
};

void writeCloud(Writer& w, const std::shared_ptr<const Cloud>& cloud)
{
  w.u8(cloud ? 1 : 0);
  if (!cloud)
  {
    return;
  }
  w.u32(static_cast<std::uint32_t>(cloud->size()));
  std::vector<unsigned char> block(cloud->size() * kPointBytes);
  unsigned char* p = block.data();
  for (const Point& q : cloud->points)
  {
    for (const float f : { q.x, q.y, q.z, q.intensity })
    {
      putBytes(p, bitCast<std::uint32_t>(f), 4);
      p += 4;
    }
  }
  w.raw(block.data(), block.size());
}

std::shared_ptr<const Cloud> readCloud(Reader& r, const std::string& what)
{
  if (!r.flag(what.c_str()))
  {
    return nullptr;
  }
  const std::uint64_t n = r.count(r.u32(), kPointBytes, what + " points");
  std::vector<unsigned char> block(n * kPointBytes);
  r.raw(block.data(), block.size());
  auto cloud = std::make_shared<Cloud>();
  cloud->points.resize(n);
  const unsigned char* p = block.data();
  for (Point& q : cloud->points)
  {
    q = Point{};
    q.x = bitCast<float>(static_cast<std::uint32_t>(getBytes(p, 4)));
    q.y = bitCast<float>(static_cast<std::uint32_t>(getBytes(p + 4, 4)));
    q.z = bitCast<float>(static_cast<std::uint32_t>(getBytes(p + 8, 4)));
    q.intensity = bitCast<float>(static_cast<std::uint32_t>(getBytes(p + 12, 4)));
    p += kPointBytes;
    if (!isFinite(q) || !std::isfinite(q.intensity))
    {
      r.fail("corrupt: a non-finite point in " + what);
    }
  }
  setUnorganized(*cloud);
  return cloud;
}

// One keyframe: stamp, session, pose, path, edge and plane clouds (or none), descriptor cells.
void writeKeyframe(Writer& w, const Keyframe& k)
{
  w.f64(k.stamp);
  w.i32(k.session);
  w.pose(k.pose);
  w.f64(k.path);
  writeCloud(w, k.corners);
  writeCloud(w, k.surfs);
  const Eigen::MatrixXf& cells = k.descriptor.cells();
  w.u32(static_cast<std::uint32_t>(cells.rows()));
  w.u32(static_cast<std::uint32_t>(cells.cols()));
  for (Eigen::Index i = 0; i < cells.rows(); ++i)
  {
    for (Eigen::Index j = 0; j < cells.cols(); ++j)
    {
      w.f32(cells(i, j));
    }
  }
}

Keyframe readKeyframe(Reader& r, std::size_t index)
{
  const std::string what = "keyframe " + std::to_string(index);
  Keyframe k;
  k.stamp = r.f64();
  k.session = r.i32();
  k.pose = r.pose(what + "'s pose");
  k.path = r.f64();
  if (!std::isfinite(k.stamp) || !std::isfinite(k.path) || k.session < 0 || k.session > kMaxSession)
  {
    r.fail("corrupt: " + what + " has a non-finite stamp or path or an impossible session");
  }
  k.corners = readCloud(r, what + "'s edge cloud");
  k.surfs = readCloud(r, what + "'s plane cloud");
  const std::uint32_t rows = r.u32(), cols = r.u32();
  if (rows > kMaxDescriptorRings || cols > kMaxDescriptorSectors || (rows == 0) != (cols == 0))
  {
    r.fail("corrupt: " + what + "'s descriptor is " + std::to_string(rows) + " x " + std::to_string(cols));
  }
  r.count(std::uint64_t(rows) * cols, 4, what + "'s descriptor cells");
  if (rows > 0)
  {
    std::vector<unsigned char> block(std::size_t(rows) * cols * 4);
    r.raw(block.data(), block.size());
    Eigen::MatrixXf cells(rows, cols);
    const unsigned char* p = block.data();
    for (Eigen::Index i = 0; i < cells.rows(); ++i)
    {
      for (Eigen::Index j = 0; j < cells.cols(); ++j, p += 4)
      {
        cells(i, j) = bitCast<float>(static_cast<std::uint32_t>(getBytes(p, 4)));
      }
    }
    if (!cells.allFinite() || (cells.array() < 0.0f).any())
    {
      r.fail("corrupt: " + what + "'s descriptor has negative or non-finite cells");
    }
    k.descriptor = ScanContext::fromCells(cells);
  }
  return k;
}

// An edge's uncertainty: its 6x6 square-root information, row by row.
void writeEdgeUncertainty(Writer& w, const PoseGraphEdge& e)
{
  for (int i = 0; i < 36; ++i)
  {
    w.f64(e.sqrt_information(i / 6, i % 6));
  }
}

void readEdgeUncertainty(Reader& r, PoseGraphEdge& e, const std::string& what)
{
  for (int i = 0; i < 36; ++i)
  {
    e.sqrt_information(i / 6, i % 6) = r.f64();
  }
  if (!e.sqrt_information.allFinite() || !(e.sqrt_information.squaredNorm() > 0.0))
  {
    r.fail("corrupt: " + what + " has an information that is not finite and non-zero");
  }
}

// One edge: from, to, the measured relative pose, its uncertainty, the loop and enabled flags.
void writeEdge(Writer& w, const PoseGraphEdge& e)
{
  w.u64(e.from);
  w.u64(e.to);
  w.pose(e.measured);
  writeEdgeUncertainty(w, e);
  w.u8(e.loop ? 1 : 0);
  w.u8(e.enabled ? 1 : 0);
}

PoseGraphEdge readEdge(Reader& r, std::size_t keyframes, std::size_t index)
{
  const std::string what = "edge " + std::to_string(index);
  PoseGraphEdge e;
  const std::uint64_t from = r.u64(), to = r.u64();
  if (from >= keyframes || to >= keyframes || from == to)
  {
    r.fail("corrupt: " + what + " joins keyframes " + std::to_string(from) + " and " + std::to_string(to) + " of " +
           std::to_string(keyframes));
  }
  e.from = static_cast<std::size_t>(from);
  e.to = static_cast<std::size_t>(to);
  e.measured = r.pose(what + "'s measurement");
  readEdgeUncertainty(r, e, what);
  e.loop = r.flag("loop");
  e.enabled = r.flag("enabled");
  return e;
}

void writeString(Writer& w, const std::string& s)
{
  w.u32(static_cast<std::uint32_t>(s.size()));
  w.raw(s.data(), s.size());
}

std::string readString(Reader& r, const char* what)
{
  const std::uint32_t n = r.u32();
  if (n > kMaxSensorName)
  {
    r.fail(std::string("corrupt: ") + what + " of " + std::to_string(n) + " bytes");
  }
  std::string s(n, '\0');
  r.raw(s.data(), n);
  return s;
}

double readSize(Reader& r, const char* what)
{
  const double v = r.f64();
  if (!std::isfinite(v) || v < 0.0)
  {
    r.fail(std::string("corrupt: ") + what + " is not a size");
  }
  return v;
}
}  // namespace

void writeGraphFile(const std::string& path, const LoopGraph& graph, const GraphFileInfo& info)
{
  if (info.sensor.size() > kMaxSensorName)
  {
    throw GraphFileError("cannot write graph " + path + ": sensor name too long");
  }
  const std::string temporary = path + ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out)
    {
      throw GraphFileError("cannot write graph " + temporary + ": " + std::strerror(errno));
    }
    try
    {
      Writer w(out, temporary);
      w.raw(kMagic, sizeof(kMagic));
      w.u32(kGraphFormatVersion);
      writeString(w, info.sensor);
      w.f64(info.cube_size);
      w.f64(info.corner_leaf_size);
      w.f64(info.surf_leaf_size);
      w.f64(graph.keyframe_corner_leaf);
      w.f64(graph.keyframe_surf_leaf);
      w.i32(graph.descriptor.rings);
      w.i32(graph.descriptor.sectors);
      w.f64(graph.descriptor.max_range);
      w.f64(graph.descriptor.lift);
      w.u64(graph.keyframes.size());
      w.u64(graph.edges.size());
      for (const Keyframe& k : graph.keyframes)
      {
        writeKeyframe(w, k);
      }
      for (const PoseGraphEdge& e : graph.edges)
      {
        writeEdge(w, e);
      }
      w.finish();
      out.close();
      if (!out)
      {
        throw GraphFileError("cannot write graph " + temporary + ": " + std::strerror(errno));
      }
    }
    catch (...)
    {
      out.close();
      std::remove(temporary.c_str());
      throw;
    }
  }
  std::error_code error;
  std::filesystem::rename(temporary, path, error);
  if (error)
  {
    std::remove(temporary.c_str());
    throw GraphFileError("cannot write graph " + path + ": " + error.message());
  }
}

GraphFile readGraphFile(const std::string& path)
{
  std::error_code error;
  const std::uintmax_t size = std::filesystem::file_size(path, error);
  if (error)
  {
    throw GraphFileError("cannot read graph " + path + ": " + error.message());
  }
  std::ifstream in(path, std::ios::binary);
  if (!in)
  {
    throw GraphFileError("cannot read graph " + path + ": " + std::strerror(errno));
  }
  Reader r(in, size, path);
  char magic[sizeof(kMagic)];
  if (size < sizeof(kMagic))
  {
    r.fail("too short to be an aloam_nodelet graph file");
  }
  r.raw(magic, sizeof(magic));
  if (std::memcmp(magic, kMagic, sizeof(kMagic)) != 0)
  {
    r.fail("not an aloam_nodelet graph file (wrong magic)");
  }
  GraphFile file;
  file.version = r.u32();
  if (file.version == 0 || file.version > kGraphFormatVersion)
  {
    r.fail("format version " + std::to_string(file.version) + " (this build reads 1 to " +
           std::to_string(kGraphFormatVersion) + ")");
  }
  file.info.sensor = readString(r, "sensor name");
  file.info.cube_size = readSize(r, "cube size");
  file.info.corner_leaf_size = readSize(r, "edge leaf size");
  file.info.surf_leaf_size = readSize(r, "plane leaf size");
  LoopGraph& g = file.graph;
  g.keyframe_corner_leaf = readSize(r, "keyframe edge leaf size");
  g.keyframe_surf_leaf = readSize(r, "keyframe plane leaf size");
  g.descriptor.rings = r.i32();
  g.descriptor.sectors = r.i32();
  g.descriptor.max_range = readSize(r, "descriptor range");
  g.descriptor.lift = r.f64();
  if (g.descriptor.rings < 1 || g.descriptor.rings > static_cast<int>(kMaxDescriptorRings) ||
      g.descriptor.sectors < 1 || g.descriptor.sectors > static_cast<int>(kMaxDescriptorSectors) ||
      !std::isfinite(g.descriptor.lift))
  {
    r.fail("corrupt: descriptor settings");
  }
  const std::uint64_t keyframes = r.count(r.u64(), kMinKeyframeBytes, "keyframes");
  const std::uint64_t edges = r.u64();
  r.count(edges, kMinEdgeBytes, "edges");
  r.count(keyframes * kMinKeyframeBytes + edges * kMinEdgeBytes, 1, "bytes of keyframes and edges");
  g.keyframes.reserve(keyframes);
  for (std::uint64_t i = 0; i < keyframes; ++i)
  {
    g.keyframes.push_back(readKeyframe(r, i));
  }
  r.count(edges, kMinEdgeBytes, "edges");
  g.edges.reserve(edges);
  for (std::uint64_t i = 0; i < edges; ++i)
  {
    g.edges.push_back(readEdge(r, g.keyframes.size(), i));
  }
  r.finish();
  return file;
}

std::vector<std::string> graphSettingsWarnings(const GraphFileInfo& saved, const GraphFileInfo& current)
{
  std::vector<std::string> out;
  if (!saved.sensor.empty() && !current.sensor.empty() && saved.sensor != current.sensor)
  {
    out.push_back("the graph was made with sensor " + saved.sensor + ", this run is " + current.sensor +
                  ": place descriptors of different sensors rarely match (nearby loops still close)");
  }
  if (saved.cube_size != current.cube_size || saved.corner_leaf_size != current.corner_leaf_size ||
      saved.surf_leaf_size != current.surf_leaf_size)
  {
    char text[240];
    std::snprintf(text, sizeof(text),
                  "the graph was mapped with cube %.1f m and leaves %.2f / %.2f m, this run uses %.1f m and "
                  "%.2f / %.2f m: the map is rebuilt with this run's",
                  saved.cube_size, saved.corner_leaf_size, saved.surf_leaf_size, current.cube_size,
                  current.corner_leaf_size, current.surf_leaf_size);
    out.push_back(text);
  }
  return out;
}

}  // namespace aloam
