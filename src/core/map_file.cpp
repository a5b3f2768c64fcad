#include "aloam_nodelet/core/map_file.h"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include <pcl/common/io.h>
#include <pcl/common/point_tests.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/impl/pcd_io.hpp>

namespace aloam
{
namespace
{
constexpr const char* kFormatName = "aloam_nodelet_map";

std::string trim(const std::string& s)
{
  const auto begin = s.find_first_not_of(" \t\r");
  if (begin == std::string::npos)
  {
    return "";
  }
  return s.substr(begin, s.find_last_not_of(" \t\r") - begin + 1);
}

double toNumber(const std::string& text, const std::string& where)
{
  std::size_t used = 0;
  double value = 0.0;
  try
  {
    value = std::stod(text, &used);
  }
  catch (const std::exception&)
  {
    used = 0;
  }
  if (used == 0 || trim(text.substr(used)) != "")
  {
    throw MapFileError(where + ": '" + text + "' is not a number");
  }
  return value;
}

// The sidecar: flat "key: value" lines and the trajectory as a list of [x, y, z] (a YAML subset that
// yaml-cpp, PyYAML and rosparam read; written and read by hand to need no YAML library).
void writeSidecar(const std::string& path, const std::string& pcd, std::size_t corners, std::size_t surfs,
                  const MapMetadata& m)
{
  std::ofstream out(path);
  if (!out)
  {
    throw MapFileError("cannot write map sidecar " + path + ": " + std::strerror(errno));
  }
  out.precision(12);  // round numbers stay round (0.4, not 0.40000000000000002)
  out << "# aloam_nodelet map: what localization needs to use the PCD again\n"
      << "format: " << kFormatName << "\nversion: " << kMapFormatVersion << "\n"
      << "pcd: " << pcd << "\nframe_id: " << m.frame_id << "\nsensor: " << (m.sensor.empty() ? "unknown" : m.sensor)
      << "\ncube_size: " << m.cube_size << "\ncorner_leaf_size: " << m.corner_leaf_size
      << "\nsurf_leaf_size: " << m.surf_leaf_size << "\nedge_points: " << corners << "\nplane_points: " << surfs
      << "\ntrajectory_positions: " << m.trajectory.size() << "\ntrajectory:" << (m.trajectory.empty() ? " []" : "")
      << "\n";
  out.precision(6);
  for (const Eigen::Vector3d& p : m.trajectory)
  {
    out << "  - [" << p.x() << ", " << p.y() << ", " << p.z() << "]\n";
  }
  if (!out.flush())
  {
    throw MapFileError("cannot write map sidecar " + path);
  }
}

struct Sidecar
{
  std::map<std::string, std::string> values;
  std::vector<Eigen::Vector3d> trajectory;
};

Sidecar readSidecar(const std::string& path)
{
  std::ifstream in(path);
  if (!in)
  {
    throw MapFileError("cannot read map sidecar " + path + ": " + std::strerror(errno));
  }
  Sidecar s;
  std::string line;
  int number = 0;
  bool in_trajectory = false;
  while (std::getline(in, line))
  {
    ++number;
    const std::string where = path + ":" + std::to_string(number);
    const std::string text = trim(line.substr(0, line.find('#')));
    if (text.empty())
    {
      continue;
    }
    if (in_trajectory && text[0] == '-')
    {
      const auto open = text.find('['), close = text.find(']');
      if (open == std::string::npos || close == std::string::npos || close < open)
      {
        throw MapFileError(where + ": a trajectory position must read - [x, y, z]");
      }
      std::stringstream list(text.substr(open + 1, close - open - 1));
      std::string item;
      std::vector<double> xyz;
      while (std::getline(list, item, ','))
      {
        xyz.push_back(toNumber(trim(item), where));
      }
      if (xyz.size() != 3)
      {
        throw MapFileError(where + ": a trajectory position needs 3 coordinates");
      }
      s.trajectory.emplace_back(xyz[0], xyz[1], xyz[2]);
      continue;
    }
    const auto colon = text.find(':');
    if (colon == std::string::npos || line[0] == ' ')
    {
      throw MapFileError(where + ": expected 'key: value', read '" + text + "'");
    }
    const std::string key = trim(text.substr(0, colon)), value = trim(text.substr(colon + 1));
    in_trajectory = key == "trajectory" && value.empty();
    s.values[key] = value;
  }
  if (s.values["format"] != kFormatName)
  {
    throw MapFileError(path + " is not an aloam_nodelet map sidecar (no 'format: " + kFormatName + "')");
  }
  return s;
}

bool hasField(const pcl::PCLPointCloud2& blob, const std::string& name, std::uint8_t* datatype = nullptr)
{
  for (const auto& f : blob.fields)
  {
    if (f.name == name)
    {
      if (datatype)
      {
        *datatype = f.datatype;
      }
      return true;
    }
  }
  return false;
}

void append(Cloud& cloud, float x, float y, float z)
{
  Point p{};
  p.x = x;
  p.y = y;
  p.z = z;
  cloud.points.push_back(p);
}
}  // namespace

std::string mapSidecarPath(const std::string& pcd)
{
  return pcd + ".yaml";
}

std::vector<Eigen::Vector3d> thinnedPositions(const std::vector<Eigen::Vector3d>& positions, double spacing)
{
  std::vector<Eigen::Vector3d> out;
  for (const Eigen::Vector3d& p : positions)
  {
    if (out.empty() || (p - out.back()).norm() >= spacing)
    {
      out.push_back(p);
    }
  }
  return out;
}

void splitMap(const CubeMap& map, Cloud& corners, Cloud& surfs)
{
  corners.clear();
  surfs.clear();
  map.forEachCube(
      [&](const CubeIndex&, const CubeMap::Cube& cube)
      {
        corners.points.insert(corners.points.end(), cube.corners.points.begin(), cube.corners.points.end());
        surfs.points.insert(surfs.points.end(), cube.surfs.points.begin(), cube.surfs.points.end());
      });
  setUnorganized(corners);
  setUnorganized(surfs);
}

void writeMapFile(const std::string& pcd, const Cloud& corners, const Cloud& surfs, const MapMetadata& metadata)
{
  if (corners.empty() && surfs.empty())
  {
    throw MapFileError("cannot write map " + pcd + ": the map is empty");
  }
  pcl::PointCloud<pcl::PointXYZL> labelled;
  labelled.points.reserve(corners.size() + surfs.size());
  for (const bool edges : { true, false })
  {
    for (const Point& p : (edges ? corners : surfs).points)
    {
      pcl::PointXYZL q;
      q.x = p.x;
      q.y = p.y;
      q.z = p.z;
      q.label = edges ? kMapEdgeLabel : kMapPlaneLabel;
      labelled.points.push_back(q);
    }
  }
  labelled.width = static_cast<std::uint32_t>(labelled.points.size());
  labelled.height = 1;
  labelled.is_dense = true;
  // PCL reports some write errors by return value and others by exception.
  bool written = false;
  try
  {
    written = pcl::io::savePCDFileBinary(pcd, labelled) == 0;
  }
  catch (const std::exception& e)
  {
    throw MapFileError("cannot write map " + pcd + ": " + e.what());
  }
  if (!written)
  {
    throw MapFileError("cannot write map " + pcd);
  }
  const std::string name = pcd.substr(pcd.find_last_of('/') + 1);
  writeSidecar(mapSidecarPath(pcd), name, corners.size(), surfs.size(), metadata);
}

MapData readMapFile(const std::string& pcd)
{
  MapData data;
  {
    std::ifstream probe(pcd);
    if (!probe)
    {
      throw MapFileError("cannot read map " + pcd + ": " + std::strerror(errno));
    }
  }
  pcl::PCLPointCloud2 blob;
  pcl::PCDReader reader;
  // PCL throws on some damage, returns an error code on other damage and crashes on a header without
  // fields or points (PCL 1.13): the header is checked first, and both other kinds become one message.
  int status = -1;
  try
  {
    Eigen::Vector4f origin;
    Eigen::Quaternionf orientation;
    int pcd_version = 0, data_type = 0;
    unsigned int data_index = 0;
    if (reader.readHeader(pcd, blob, origin, orientation, pcd_version, data_type, data_index) != 0)
    {
      throw MapFileError("cannot read map " + pcd + ": no readable PCD header");
    }
    const std::uintmax_t points = static_cast<std::uintmax_t>(blob.width) * blob.height;
    if (blob.fields.empty() || points == 0 || blob.point_step == 0)
    {
      throw MapFileError("cannot read map " + pcd + ": the PCD header declares no fields or no points");
    }
    // Binary data must be all there (ASCII and compressed data PCL checks itself).
    if (data_type == 1 && std::filesystem::file_size(pcd) < data_index + points * blob.point_step)
    {
      throw MapFileError("cannot read map " + pcd + ": the file is shorter than its header says (truncated?)");
    }
    status = reader.read(pcd, blob);
  }
  catch (const MapFileError&)
  {
    throw;
  }
  catch (const std::exception& e)
  {
    throw MapFileError("cannot read map " + pcd + ": " + e.what());
  }
  if (status != 0)
  {
    throw MapFileError("cannot read map " + pcd + ": not a readable PCD file");
  }
  std::uint8_t tx = 0, ty = 0, tz = 0;
  if (!hasField(blob, "x", &tx) || !hasField(blob, "y", &ty) || !hasField(blob, "z", &tz))
  {
    throw MapFileError("map " + pcd + " has no x y z fields");
  }
  if (tx != pcl::PCLPointField::FLOAT32 || ty != pcl::PCLPointField::FLOAT32 || tz != pcl::PCLPointField::FLOAT32)
  {
    throw MapFileError("map " + pcd + ": x y z must be 32-bit floats");
  }
  std::uint8_t label_type = 0;
  const bool labelled = hasField(blob, "label", &label_type) && label_type == pcl::PCLPointField::UINT32;
  std::size_t unlabelled = 0;
  std::size_t non_finite = 0;  // other tools' clouds may hold NaN points (holes of an organized cloud)
  if (labelled)
  {
    pcl::PointCloud<pcl::PointXYZL> cloud;
    pcl::fromPCLPointCloud2(blob, cloud);
    for (const auto& p : cloud.points)
    {
      if (!pcl::isFinite(p))
      {
        ++non_finite;
        continue;
      }
      unlabelled += p.label != kMapEdgeLabel && p.label != kMapPlaneLabel;
      append(p.label == kMapEdgeLabel ? data.corners : data.surfs, p.x, p.y, p.z);
    }
    if (unlabelled > 0)
    {
      data.warnings.push_back(std::to_string(unlabelled) +
                              " points with a label other than edge (1) or plane (2) "
                              "taken as plane points");
    }
  }
  else
  {
    pcl::PointCloud<pcl::PointXYZ> cloud;
    pcl::fromPCLPointCloud2(blob, cloud);
    for (const auto& p : cloud.points)
    {
      if (!pcl::isFinite(p))
      {
        ++non_finite;
        continue;
      }
      append(data.surfs, p.x, p.y, p.z);
    }
    data.warnings.push_back("no edge/plane label in " + pcd +
                            " (an older build's map or another tool's cloud): every point taken as a plane point");
  }
  if (non_finite > 0)
  {
    data.warnings.push_back(std::to_string(non_finite) + " points of " + pcd +
                            " with a NaN or infinite coordinate dropped");
  }
  data.dropped_non_finite = non_finite;
  setUnorganized(data.corners);
  setUnorganized(data.surfs);
  if (data.corners.empty() && data.surfs.empty())
  {
    throw MapFileError("map " + pcd + " has no finite points");
  }

  const std::string sidecar = mapSidecarPath(pcd);
  if (!std::ifstream(sidecar))
  {
    data.warnings.push_back("no sidecar " + sidecar +
                            ": frame and mapping parameters are the defaults, and a global search tries every "
                            "part of the map instead of the mapped trajectory (slower)");
    return data;
  }
  const Sidecar s = readSidecar(sidecar);
  auto number = [&](const std::string& key, double fallback)
  {
    const auto it = s.values.find(key);
    return it == s.values.end() ? fallback : toNumber(it->second, sidecar + " " + key);
  };
  data.version = static_cast<int>(number("version", 0));
  if (data.version < 1 || data.version > kMapFormatVersion)
  {
    throw MapFileError(sidecar + ": format version " + std::to_string(data.version) + " (this build reads 1 to " +
                       std::to_string(kMapFormatVersion) + ")");
  }
  MapMetadata& m = data.metadata;
  if (s.values.count("frame_id") && !s.values.at("frame_id").empty())
  {
    m.frame_id = s.values.at("frame_id");
  }
  if (s.values.count("sensor") && s.values.at("sensor") != "unknown")
  {
    m.sensor = s.values.at("sensor");
  }
  m.cube_size = number("cube_size", m.cube_size);
  m.corner_leaf_size = number("corner_leaf_size", m.corner_leaf_size);
  m.surf_leaf_size = number("surf_leaf_size", m.surf_leaf_size);
  if (!(m.cube_size > 0.0))
  {
    throw MapFileError(sidecar + ": cube_size must be positive");
  }
  m.trajectory = s.trajectory;
  const double edges = number("edge_points", -1), planes = number("plane_points", -1);
  if (labelled && ((edges >= 0 && edges != static_cast<double>(data.corners.size())) ||
                   (planes >= 0 && planes != static_cast<double>(data.surfs.size()))))
  {
    throw MapFileError(sidecar + " does not belong to " + pcd + ": it counts " +
                       std::to_string(static_cast<long>(edges)) + " edge and " +
                       std::to_string(static_cast<long>(planes)) + " plane points, the PCD holds " +
                       std::to_string(data.corners.size()) + " and " + std::to_string(data.surfs.size()));
  }
  return data;
}

}  // namespace aloam
