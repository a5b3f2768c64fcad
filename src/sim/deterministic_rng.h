// Deterministic random numbers for scene generation (internal to the simulator).
#pragma once

#include <random>

namespace aloam
{
namespace sim
{
/// std::mt19937's output sequence is fixed by the standard and the conversion to doubles is explicit here
/// (the distributions of <random> differ between libraries), so scenes are identical on all platforms.
class DeterministicRng
{
public:
  explicit DeterministicRng(unsigned seed) : engine_(seed) {}

  /// Uniform in [0, 1) with 53 random bits.
  double uniform01()
  {
    constexpr double kTwoTo26 = 67108864.0;
    constexpr double kTwoTo53 = 9007199254740992.0;
    const double high = static_cast<double>(engine_() >> 5);
    const double low = static_cast<double>(engine_() >> 6);
    return (high * kTwoTo26 + low) / kTwoTo53;
  }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform01(); }
  bool bernoulli(double p) { return uniform01() < p; }

private:
  std::mt19937 engine_;
};

}  // namespace sim
}  // namespace aloam
