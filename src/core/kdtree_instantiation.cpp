// pcl::KdTreeFLANN compiled once for the core's point type, so that no other translation unit needs
// PCL's template implementation.
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/kdtree/impl/kdtree_flann.hpp>

#include "aloam_nodelet/core/point_types.h"

template class pcl::KdTreeFLANN<aloam::PointXYZIRT>;
