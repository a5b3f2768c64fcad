// Saved maps: the edge and plane points of a CubeMap in one PCD, with a sidecar YAML of what localization
// needs to use them again (frame, the mapping parameters, the mapped trajectory).
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "aloam_nodelet/core/cube_map.h"
#include "aloam_nodelet/core/point_types.h"

namespace aloam
{
/// PCD `label` values: pcl_viewer colours the points by it, and the reader tells the layers apart by it.
constexpr std::uint32_t kMapEdgeLabel = 1;
constexpr std::uint32_t kMapPlaneLabel = 2;
/// Written into the sidecar; the reader accepts this version and older ones.
constexpr int kMapFormatVersion = 1;

struct MapMetadata
{
  std::string frame_id = "camera_init";
  std::string sensor;  ///< preset name, empty when unknown
  double cube_size = 50.0;
  double corner_leaf_size = 0.4;
  double surf_leaf_size = 0.8;
  /// Mapped sensor positions (map frame), thinned; candidates for global localization.
  std::vector<Eigen::Vector3d> trajectory;
};

struct MapData
{
  Cloud corners;
  Cloud surfs;
  MapMetadata metadata;
  /// 0: no sidecar (an older build's map or another tool's cloud), metadata is the defaults.
  int version = 0;
  /// Points the file held with a NaN or infinite coordinate: dropped (and said in `warnings`).
  std::size_t dropped_non_finite = 0;
  /// What the reader had to assume or drop, e.g. every point taken as a plane point.
  std::vector<std::string> warnings;
};

/// A map file that cannot be read; what() says which file and why.
class MapFileError : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

/// `pcd` with ".yaml" appended: the sidecar of a map file.
std::string mapSidecarPath(const std::string& pcd);

/// The positions, each kept one at least `spacing` from the one kept before it: the mapped trajectory a
/// sidecar stores.
std::vector<Eigen::Vector3d> thinnedPositions(const std::vector<Eigen::Vector3d>& positions, double spacing);

/// The edge and plane points of every cube of `map`.
void splitMap(const CubeMap& map, Cloud& corners, Cloud& surfs);

/// Writes `pcd` (binary, x y z label) and its sidecar; throws MapFileError on failure.
void writeMapFile(const std::string& pcd, const Cloud& corners, const Cloud& surfs, const MapMetadata& metadata);

/// Reads a map written by writeMapFile, a map of an older build (x y z intensity time ring, no sidecar:
/// plane points, with a warning) or any PCD with x y z (plane points). Points with a non-finite coordinate
/// are dropped and counted. Throws MapFileError with the reason
/// when the file is missing, is no PCD, has no x y z, or its sidecar is unreadable or disagrees with it.
MapData readMapFile(const std::string& pcd);

}  // namespace aloam
