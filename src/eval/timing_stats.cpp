#include "aloam_nodelet/eval/timing_stats.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

namespace aloam
{
namespace eval
{
SeriesStats summarize(std::vector<double> values)
{
  SeriesStats stats;
  stats.count = values.size();
  if (values.empty())
  {
    return stats;
  }
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  stats.mean = std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(n);
  stats.median = values[n / 2];
  // Nearest rank: the smallest value with at least 90 % of the values at or below it.
  const auto rank = static_cast<std::size_t>(std::ceil(0.9 * static_cast<double>(n)));
  stats.p90 = values[std::clamp<std::size_t>(rank, 1, n) - 1];
  stats.max = values.back();
  return stats;
}

std::string formatMs(const SeriesStats& stats)
{
  if (stats.count == 0)
  {
    return "n/a";
  }
  char text[128];
  std::snprintf(text, sizeof(text), "mean %6.1f  median %6.1f  p90 %6.1f ms", stats.mean, stats.median, stats.p90);
  return text;
}

}  // namespace eval
}  // namespace aloam
