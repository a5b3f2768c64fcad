// Splitting a loop over a few threads (the correspondence searches, the rings of a sweep).
#pragma once

#include <algorithm>
#include <thread>
#include <vector>

namespace aloam
{
/// Calls body(begin, end, part) for `parts` contiguous, nearly equal chunks of [0, count), part 0 on the
/// calling thread and the others on threads of their own, and returns when all are done. With one
/// part, or too little work to pay for a thread start (tens of microseconds), everything runs here.
/// Chunks write to disjoint outputs, so results do not depend on the number of parts.
template <typename Body>
void parallelChunks(int count, int parts, int min_chunk, Body&& body)
{
  parts = std::clamp(parts, 1, std::max(1, count / std::max(1, min_chunk)));
  if (parts <= 1)
  {
    body(0, count, 0);
    return;
  }
  std::vector<std::thread> helpers;
  helpers.reserve(static_cast<std::size_t>(parts - 1));
  const auto bound = [&](int part) { return static_cast<int>(static_cast<long long>(count) * part / parts); };
  for (int part = 1; part < parts; ++part)
  {
    helpers.emplace_back([&body, &bound, part] { body(bound(part), bound(part + 1), part); });
  }
  try
  {
    body(0, bound(1), 0);
  }
  catch (...)
  {
    for (std::thread& t : helpers)
    {
      t.join();
    }
    throw;
  }
  for (std::thread& t : helpers)
  {
    t.join();
  }
}

}  // namespace aloam
