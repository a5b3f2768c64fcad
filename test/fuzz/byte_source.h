// The fuzzers' reader of their input bytes: values off the front, zeros once the input is used up.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

namespace aloam_fuzz
{
class ByteSource
{
public:
  ByteSource(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}

  std::uint8_t byte() { return pos_ < size_ ? data_[pos_++] : 0; }
  std::uint32_t u16() { return static_cast<std::uint32_t>(byte()) | (static_cast<std::uint32_t>(byte()) << 8); }
  std::int16_t i16() { return static_cast<std::int16_t>(u16()); }
  float f32()
  {
    std::uint32_t bits = 0;
    for (int i = 0; i < 4; ++i)
    {
      bits |= static_cast<std::uint32_t>(byte()) << (8 * i);
    }
    float f;
    std::memcpy(&f, &bits, sizeof f);
    return f;
  }
  // Mostly a plain value (centimetres over +-327 m); one in 16 an arbitrary float (NaN, Inf, huge).
  float coordinate() { return (byte() & 15) == 0 ? f32() : static_cast<float>(i16()) / 100.0f; }
  const std::uint8_t* rest() const { return data_ + pos_; }
  std::size_t left() const { return pos_ < size_ ? size_ - pos_ : 0; }

private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
};

/// A property the code under test broke: abort, so that libFuzzer keeps the input.
inline void require(bool condition)
{
  if (!condition)
  {
    std::abort();
  }
}
}  // namespace aloam_fuzz
