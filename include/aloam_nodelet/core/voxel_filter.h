// Voxel-grid downsampling to one centroid per occupied voxel.
#pragma once

#include <cstddef>

#include "aloam_nodelet/core/point_types.h"

namespace aloam
{
/// Replaces the points of each occupied voxel (a cube of side `leaf_size`, aligned to multiples of it)
/// by their centroid; intensity and time are averaged, ring is taken from the first point of the voxel.
/// Non-finite points are dropped. `leaf_size <= 0` copies the finite points. Unlike pcl::VoxelGrid it has
/// no limit on the extent of the cloud relative to the leaf size. Appends to `out`; `in` and `out` may not
/// be the same cloud. Returns the number of points appended.
std::size_t voxelDownsample(const Cloud& in, double leaf_size, Cloud& out);

/// Downsamples `cloud` in place.
void voxelDownsampleInPlace(Cloud& cloud, double leaf_size);

}  // namespace aloam
