// Reading KITTI odometry sequences (velodyne/*.bin) and the settings that suit them.
#pragma once

#include <string>
#include <vector>

#include "aloam_nodelet/core/pipeline.h"
#include "aloam_nodelet/core/point_types.h"

namespace aloam
{
namespace io
{
/// Vertical angle correction for KITTI's HDL-64 scans, in degrees. KITTI's point clouds carry a small
/// intrinsic elevation error; 0.205 deg is the value KISS-ICP applies (IMLS-SLAM reports about 0.22 deg).
constexpr double kKittiVerticalCorrectionDeg = 0.205;
/// KITTI's recording car occupies the nearest few metres around the sensor (A-LOAM's KITTI launch: 5 m).
constexpr double kKittiMinimumRange = 5.0;

/// The sorted paths of `sequence_dir`/velodyne/*.bin. Throws std::runtime_error if there are none.
std::vector<std::string> listKittiScans(const std::string& sequence_dir);

/// Reads one KITTI scan: little-endian float32 records (x, y, z, reflectance). Ring and time are left 0
/// (KITTI has neither). Throws std::runtime_error if the file cannot be read.
void readKittiScan(const std::string& path, Cloud& out);

/// Raises the elevation of every point by `degrees` (rotation about the horizontal axis perpendicular to
/// the point's bearing), keeping its range.
void correctVerticalAngle(Cloud& cloud, double degrees);

/// Pipeline settings for KITTI: HDL-64 rings, 5 m minimum range, no deskewing (KITTI's scans are
/// already motion-compensated), no occlusion rejection (measured slightly worse there).
PipelineConfig kittiPipelineConfig();

}  // namespace io
}  // namespace aloam
