// Summaries of per-frame timings (and other series) for the tools' reports.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

namespace aloam
{
namespace eval
{
struct SeriesStats
{
  std::size_t count = 0;
  double mean = std::numeric_limits<double>::quiet_NaN();
  double median = std::numeric_limits<double>::quiet_NaN();
  double p90 = std::numeric_limits<double>::quiet_NaN();
  double max = std::numeric_limits<double>::quiet_NaN();
};

/// Mean, median (upper median), 90th percentile (nearest rank) and maximum; NaN when empty.
SeriesStats summarize(std::vector<double> values);

/// "mean   12.3  median   12.0  p90   14.1 ms", or "n/a" when empty.
std::string formatMs(const SeriesStats& stats);

}  // namespace eval
}  // namespace aloam
