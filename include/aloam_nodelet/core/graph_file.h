// Saved pose graphs: the loop closure's keyframes (pose, clouds, place descriptor) and edges in one binary
// file, so that a later run can load them and extend the same map (LoopClosure::importGraph). The layout is
// in docs/loop_closure.md ("The graph file"). ROS-free.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "aloam_nodelet/core/loop_closure.h"

namespace aloam
{
/// Written into the file; the reader accepts this version and older ones.
constexpr std::uint32_t kGraphFormatVersion = 1;

/// The mapping settings of the run that saved the graph (what decides whether its clouds suit another run).
struct GraphFileInfo
{
  std::string sensor;  ///< preset name, empty when unknown
  double cube_size = 50.0;
  double corner_leaf_size = 0.4;
  double surf_leaf_size = 0.8;
};

struct GraphFile
{
  std::uint32_t version = kGraphFormatVersion;
  GraphFileInfo info;
  LoopGraph graph;
};

/// A graph file that cannot be written or read; what() says which file and why.
class GraphFileError : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

/// Writes `graph` to `path` (through a temporary file beside it, renamed at the end, so that a failed write
/// leaves an older file as it was). Throws GraphFileError.
void writeGraphFile(const std::string& path, const LoopGraph& graph, const GraphFileInfo& info);

/// Reads a file writeGraphFile wrote. Throws GraphFileError with the reason for a missing file, another
/// format (magic), a newer version, a truncated or corrupt file (sizes beyond the file, a checksum that
/// disagrees, non-finite poses, edges to unknown keyframes); counts are checked against the bytes left
/// before anything is allocated. Keyframe clouds come back with x y z and intensity (time and ring 0).
GraphFile readGraphFile(const std::string& path);

/// How the saved settings differ from the current ones, one sentence each (empty when they agree).
std::vector<std::string> graphSettingsWarnings(const GraphFileInfo& saved, const GraphFileInfo& current);

}  // namespace aloam
